#![no_main]
lineflow_fuzz::fuzz_target_for!("colmap_images_bin");
