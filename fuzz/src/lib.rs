//! The body every fuzz target shares: the input written to a scratch file and read by the parser of
//! `lineflow_fuzzing::TARGETS` with that key. A panic or an abort is what libFuzzer reports.
pub use libfuzzer_sys;

/// The process's folder for its inputs: `LINEFLOW_FUZZ_SCRATCH`, which `fuzz/run` sets and removes (libFuzzer ends
/// the process without unwinding, so a `tempfile::TempDir` would stay behind too), else one in /dev/shm.
pub fn scratch() -> &'static std::path::Path {
    static DIR: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::var_os("LINEFLOW_FUZZ_SCRATCH").map_or_else(
            || std::path::Path::new("/dev/shm").join(format!("lineflow-fuzz-{}", std::process::id())),
            std::path::PathBuf::from,
        );
        std::fs::create_dir_all(&dir).expect("cannot make the fuzzer's scratch folder");
        dir
    })
}

/// Defines the fuzz target of the parser with this key.
#[macro_export]
macro_rules! fuzz_target_for {
    ($key:literal) => {
        $crate::libfuzzer_sys::fuzz_target!(|input: &[u8]| {
            let target = lineflow_fuzzing::target($key).expect("no such target");
            target.run(input, $crate::scratch()).expect("cannot write the input");
        });
    };
}
