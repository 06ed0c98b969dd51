//! Shared-memory housekeeping: free space in `/dev/shm` and removal of a run's leftover files.
use std::path::Path;

/// The shared-memory file system iceoryx2 uses on Linux.
pub const SHM_DIR: &str = "/dev/shm";

/// Free bytes of the file system holding `path`, or `None` when it cannot be queried.
pub fn free_bytes(path: &Path) -> Option<u64> {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).ok()?;
    let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: `c` is a valid NUL-terminated path and `s` a writable statvfs.
    let r = unsafe { libc::statvfs(c.as_ptr(), &mut s) };
    (r == 0).then(|| s.f_bavail as u64 * s.f_frsize as u64)
}

/// Files in `/dev/shm` whose name starts with `prefix`.
pub fn files_with_prefix(prefix: &str) -> Vec<std::path::PathBuf> {
    std::fs::read_dir(SHM_DIR)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(prefix))
        .map(|e| e.path())
        .collect()
}

/// Removes every `/dev/shm` file of a run; returns how many were removed. Only for runs whose processes are gone.
pub fn remove_prefixed(prefix: &str) -> usize {
    assert!(prefix.len() >= 4, "refusing to remove /dev/shm files by a short prefix");
    files_with_prefix(prefix)
        .into_iter()
        .filter(|p| std::fs::remove_file(p).is_ok())
        .count()
}

/// Human-readable bytes.
pub fn human_bytes(b: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u < UNITS.len() - 1 {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}
