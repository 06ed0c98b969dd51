#![no_main]
lineflow_fuzz::fuzz_target_for!("metashape_cameras");
