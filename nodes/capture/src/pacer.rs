//! Frame stamps from a fixed start (or the clock) at `fps`, and the pacing of a live source: what makes a
//! capture's stamps, and so a run's recording, the same on every run.
use std::time::{Duration, Instant};

use lineflow_messages::Stamp;

/// Fixed capture start (2020-09-13T12:26:40Z) so that runs and replays carry the same stamps.
pub const FIXED_START_NS: u64 = 1_600_000_000_000_000_000;

/// Frame stamps `start + k / fps` and, for a live source, the wait until frame k is due.
pub struct Pacer {
    start_ns: u64,
    period_ns: u64,
    live: bool,
    t0: Instant,
}

impl Pacer {
    /// A pacer at `fps` (0 = as fast as the graph accepts, stamped one second apart).
    ///
    /// # Errors
    /// The system clock is before 1970.
    pub fn new(fps: f64, use_clock: bool) -> Result<Pacer, std::time::SystemTimeError> {
        let start_ns = if use_clock {
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH)?.as_nanos() as u64
        } else {
            FIXED_START_NS
        };
        Ok(Pacer {
            start_ns,
            period_ns: if fps > 0.0 { (1e9 / fps) as u64 } else { 1_000_000_000 },
            live: fps > 0.0,
            t0: Instant::now(),
        })
    }

    /// The stamp of the latched topics.
    pub fn once(&self) -> Stamp {
        Stamp {
            capture_time_ns: self.start_ns,
            ..Default::default()
        }
    }

    /// Sleeps until frame `frame` is due (live sources only) and returns its stamp.
    pub fn frame(&self, frame: u64) -> Stamp {
        if self.live {
            let due = self.t0 + Duration::from_nanos(frame * self.period_ns);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        Stamp {
            frame,
            capture_time_ns: self.start_ns + frame * self.period_ns,
            ..Default::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_start_at_the_fixed_start_one_period_apart() {
        let p = Pacer::new(0.0, false).unwrap();
        assert_eq!(p.once().capture_time_ns, FIXED_START_NS);
        let s = p.frame(3);
        assert_eq!((s.frame, s.capture_time_ns), (3, FIXED_START_NS + 3_000_000_000));
        let fast = Pacer::new(1000.0, false).unwrap();
        assert_eq!(fast.frame(2).capture_time_ns, FIXED_START_NS + 2_000_000);
    }
}
