#![no_main]
lineflow_fuzz::fuzz_target_for!("exif_camera");
