//! Renders one synthetic frame to a PNG: `cargo run --release --example render_one PRESET SCALE FRAME OUT.png`.
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let syn = lineflow_capture::synth::Synthetic::new(&a[1], a[2].parse().unwrap(), 7).unwrap();
    let frame: usize = a[3].parse().unwrap();
    let _ = syn.render(frame);
    let t = std::time::Instant::now();
    let rgb = syn.render(frame);
    eprintln!(
        "{} faces, {} edges, {}x{} in {:?}",
        syn.building.faces.len(),
        syn.building.edges.len(),
        syn.camera().width,
        syn.camera().height,
        t.elapsed()
    );
    image::save_buffer(&a[4], &rgb, syn.camera().width, syn.camera().height, image::ExtendedColorType::Rgb8).unwrap();
}
