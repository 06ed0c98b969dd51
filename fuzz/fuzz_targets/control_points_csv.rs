#![no_main]
lineflow_fuzz::fuzz_target_for!("control_points_csv");
