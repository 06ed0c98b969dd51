//! The Python the end-to-end tests run: a virtual environment in `target/python-env` holding
//! `tests/e2e/requirements.txt`, made on first use, so that `cargo test --workspace` needs nothing but Python 3
//! on the machine. Test processes run in parallel and cargo runs test binaries one after another; a lock file
//! makes one of them build the environment while the others wait, and a stamp holding the requirements' text
//! makes the next run reuse it (and rebuild it when the requirements change).
use std::ffi::OsString;
use std::fs::File;
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

const REQUIREMENTS: &str = include_str!("../requirements.txt");
const STAMP: &str = "lineflow-requirements.txt";

/// The environment's `python3`, built on first use.
///
/// # Panics
/// When `python3` is missing, cannot make a virtual environment, or pip cannot install the requirements; the
/// message says what to install.
pub fn python() -> PathBuf {
    env_dir().join("bin").join("python3")
}

/// `PATH` with the environment's `bin/` first, for child processes that start `python3` themselves.
pub fn python_path() -> OsString {
    let mut dirs = vec![env_dir().join("bin")];
    dirs.extend(std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()));
    std::env::join_paths(dirs).expect("PATH entries hold no separator")
}

fn env_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = crate::bin_dir().parent().expect("target/<profile> has a parent").join("python-env");
        ensure(&dir);
        dir
    })
}

fn ensure(dir: &Path) {
    let lock_path = dir.with_extension("lock");
    let lock = File::create(&lock_path).unwrap_or_else(|e| panic!("{}: {e}", lock_path.display()));
    // SAFETY: flock on a descriptor this function owns for its whole body; released when `lock` is dropped.
    if unsafe { libc::flock(lock.as_raw_fd(), libc::LOCK_EX) } != 0 {
        panic!("{}: cannot lock: {}", lock_path.display(), std::io::Error::last_os_error());
    }
    if std::fs::read_to_string(dir.join(STAMP)).is_ok_and(|s| s == REQUIREMENTS) {
        return;
    }
    eprintln!("making the tests' Python environment in {} (once; about a minute)", dir.display());
    let _ = std::fs::remove_dir_all(dir);
    let python3 = std::env::var_os("LINEFLOW_TEST_PYTHON").unwrap_or_else(|| "python3".into());
    run(
        Command::new(&python3).args(["-m", "venv"]).arg(dir),
        "python3 -m venv (install Python 3 with its venv module, e.g. Debian's python3-venv, or point LINEFLOW_TEST_PYTHON at one)",
    );
    let requirements = dir.join("requirements.txt");
    std::fs::write(&requirements, REQUIREMENTS).expect("write requirements");
    run(
        Command::new(dir.join("bin").join("python3"))
            .args(["-m", "pip", "install", "--quiet", "--disable-pip-version-check", "-r"])
            .arg(&requirements),
        "pip install -r tests/e2e/requirements.txt (needs the Python package index)",
    );
    std::fs::write(dir.join(STAMP), REQUIREMENTS).expect("write the environment's stamp");
}

fn run(cmd: &mut Command, what: &str) {
    let out = cmd.output().unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(
        out.status.success(),
        "{what} failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
