//! Faults injected on purpose (`lineflow run --chaos NODE@FRAME[:stop=S]`): the supervisor SIGKILLs a node, or
//! SIGSTOPs it for a while and continues it, once the node has received the given frame. A user tries a launch
//! file's restart policies and history depths on a real run this way; `lineflow bench chaos` does it to every node
//! in turn.
use std::fmt;
use std::str::FromStr;
use std::time::Duration;

/// What is done to the node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Action {
    /// SIGKILL: a crash the node cannot clean up after.
    Kill,
    /// SIGSTOP, then SIGCONT after this long: a hang that comes back (a debugger, a suspended laptop).
    Stop(Duration),
}

/// One fault of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    /// The node, by its name in the launch file.
    pub node: String,
    /// The frame after which the fault strikes: once the node has received it (a source: once the furthest stage
    /// has, a source having no inputs of its own).
    pub frame: u64,
    /// What is done.
    pub action: Action,
}

/// Why a `--chaos` value cannot be read.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("--chaos {spec:?}: {why} (expected NODE@FRAME or NODE@FRAME:stop=SECONDS, e.g. edges@5 or lines2d@3:stop=2)")]
pub struct BadFault {
    spec: String,
    why: String,
}

impl FromStr for Fault {
    type Err = BadFault;

    fn from_str(spec: &str) -> Result<Self, Self::Err> {
        let bad = |why: &str| BadFault {
            spec: spec.to_owned(),
            why: why.to_owned(),
        };
        let (node, rest) = spec.split_once('@').ok_or_else(|| bad("no '@'"))?;
        if node.is_empty() {
            return Err(bad("no node name"));
        }
        let (frame, option) = match rest.split_once(':') {
            Some((f, o)) => (f, Some(o)),
            None => (rest, None),
        };
        let frame = frame.parse().map_err(|_| bad("the frame is not a whole number"))?;
        let action = match option {
            None => Action::Kill,
            Some(o) => {
                let seconds: f64 = o
                    .strip_prefix("stop=")
                    .ok_or_else(|| bad("the only option is stop=SECONDS"))?
                    .parse()
                    .map_err(|_| bad("stop= takes seconds"))?;
                let pause = Duration::try_from_secs_f64(seconds)
                    .ok()
                    .filter(|d| *d <= Duration::from_secs(3600))
                    .ok_or_else(|| bad("stop= takes 0 to 3600 seconds"))?;
                Action::Stop(pause)
            }
        };
        Ok(Fault {
            node: node.to_owned(),
            frame,
            action,
        })
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.action {
            Action::Kill => write!(f, "SIGKILL to '{}' after frame {}", self.node, self.frame),
            Action::Stop(d) => write!(
                f,
                "SIGSTOP to '{}' after frame {} for {:.1} s",
                self.node,
                self.frame,
                d.as_secs_f64()
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kill_and_a_stop_are_read_and_shown() {
        let kill: Fault = "edges@5".parse().unwrap();
        assert_eq!(
            kill,
            Fault {
                node: "edges".into(),
                frame: 5,
                action: Action::Kill
            }
        );
        assert_eq!(kill.to_string(), "SIGKILL to 'edges' after frame 5");
        let stop: Fault = "lines2d@0:stop=2.5".parse().unwrap();
        assert_eq!(stop.action, Action::Stop(Duration::from_millis(2500)));
        assert_eq!(stop.to_string(), "SIGSTOP to 'lines2d' after frame 0 for 2.5 s");
    }

    #[test]
    fn a_bad_value_names_what_is_wrong() {
        for (spec, why) in [
            ("edges", "no '@'"),
            ("@3", "no node name"),
            ("edges@x", "not a whole number"),
            ("edges@-1", "not a whole number"),
            ("edges@3:kill", "the only option"),
            ("edges@3:stop=x", "stop= takes seconds"),
            ("edges@3:stop=-1", "0 to 3600"),
            ("edges@3:stop=inf", "0 to 3600"),
        ] {
            let e = spec.parse::<Fault>().unwrap_err().to_string();
            assert!(e.contains(why) && e.contains(spec), "{spec}: {e}");
        }
    }
}
