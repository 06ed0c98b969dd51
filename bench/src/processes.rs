//! A run's node processes as `/proc` shows them: found among the supervisor's children by the node's environment
//! (`lineflow bench chaos` signals them, `lineflow bench soak` samples them).

/// The node processes among the children of `parent` (a supervisor): (node name, pid), by pid.
pub fn node_processes(parent: u32) -> Vec<(String, i32)> {
    let prefix = format!("{}=", lineflow_runtime::env::NODE);
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    let mut found: Vec<(String, i32)> = entries
        .flatten()
        .filter_map(|e| {
            let pid: i32 = e.file_name().to_str()?.parse().ok()?;
            let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
            let ppid: u32 = stat.get(stat.rfind(')')? + 2..)?.split(' ').nth(1)?.parse().ok()?;
            if ppid != parent {
                return None;
            }
            let environ = std::fs::read(format!("/proc/{pid}/environ")).ok()?;
            let name = environ
                .split(|b| *b == 0)
                .find_map(|v| v.strip_prefix(prefix.as_bytes()))
                .map(|n| String::from_utf8_lossy(n).into_owned())?;
            Some((name, pid))
        })
        .collect();
    found.sort_by_key(|(_, pid)| *pid);
    found
}

/// The process of node `name` among the children of `parent`.
pub fn node_pid(parent: u32, name: &str) -> Option<i32> {
    node_processes(parent).into_iter().find_map(|(n, pid)| (n == name).then_some(pid))
}

/// What a process holds, from `/proc/PID/status` and `/proc/PID/fd`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Usage {
    /// Resident memory, kB (`VmRSS`).
    pub rss_kb: u64,
    /// Of it, shared memory mapped and touched, kB (`RssShmem`: the iceoryx2 segments).
    pub shmem_kb: u64,
    /// Open file descriptors.
    pub open_files: u64,
}

/// The usage of process `pid`; `None` once it has gone.
pub fn usage(pid: i32) -> Option<Usage> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let field = |name: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.split_whitespace().next()?.parse().ok())
            .unwrap_or(0)
    };
    let open_files = std::fs::read_dir(format!("/proc/{pid}/fd")).ok()?.count() as u64;
    Some(Usage {
        rss_kb: field("VmRSS:"),
        shmem_kb: field("RssShmem:"),
        open_files,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_child_is_found_by_its_node_name_and_its_usage_read() {
        let mut child = std::process::Command::new("sleep")
            .arg("30")
            .env(lineflow_runtime::env::NODE, "probe")
            .spawn()
            .unwrap();
        let me = std::process::id();
        let pid = (0..200)
            .find_map(|_| {
                node_pid(me, "probe").or_else(|| {
                    std::thread::sleep(std::time::Duration::from_millis(10));
                    None
                })
            })
            .expect("the child is listed");
        assert_eq!(pid, child.id() as i32);
        assert_eq!(node_pid(me, "other"), None);
        let u = usage(pid).unwrap();
        assert!(u.rss_kb > 0 && u.open_files >= 3, "{u:?}");
        child.kill().unwrap();
        child.wait().unwrap();
        assert_eq!(usage(pid), None, "gone once reaped");
    }
}
