//! Camera set-ups modelled on the thesis data sets (seed 000 §3, `docs/sources.md`) and two more geometries.
use lineflow_photogrammetry::{look_at, rotation_from_opk, Camera, Pose, Vec3};

use super::geometry::Material;
use super::render::Sensor;
use super::rng::Rng;
use super::scene::BuildingSpec;

/// Names of the presets.
pub const PRESETS: [&str; 4] = ["d2x-strip", "a55-two-strips", "convergent", "roof"];

/// A camera, a building, the camera stations, and the sensor.
#[derive(Debug, Clone)]
pub struct Preset {
    /// Preset name, with `@N` when the building is variant `N` ([`BuildingSpec::varied`]).
    pub name: String,
    /// One-line description.
    pub description: &'static str,
    /// Interior orientation at full size.
    pub camera: Camera,
    /// The building.
    pub building: BuildingSpec,
    /// Exterior orientation of every image, in capture order.
    pub poses: Vec<Pose>,
    /// Optics and sensor.
    pub sensor: Sensor,
    /// Standard deviation of the simulated target measurements, pixels.
    pub obs_sigma_px: f64,
    /// Standard deviation stated for the surveyed control points, metres.
    pub survey_sigma_m: f64,
}

/// Nikon D2X, calibrated values of Table 4-2; k1 gives ≈ 100 µm radial distortion at the corner.
fn d2x() -> Camera {
    Camera {
        width: 4288,
        height: 2848,
        pixel_size_mm: 0.0055,
        focal_mm: 17.606,
        principal_point_mm: [-0.107, 0.016],
        radial: [3.5e-5, 0.0, 0.0],
        decentering: [6e-6, -4e-6],
    }
}

/// Sony A55, Table 4-2; k1 gives ≈ 494 µm (≈ 103 px) at the corner.
fn a55() -> Camera {
    Camera {
        width: 4912,
        height: 3264,
        pixel_size_mm: 0.0048,
        focal_mm: 18.007,
        principal_point_mm: [-0.229, 0.1067],
        radial: [1.74e-4, 0.0, 0.0],
        decentering: [7e-6, -5e-6],
    }
}

fn building(width_m: f64, window_columns: u32) -> BuildingSpec {
    BuildingSpec {
        width_m,
        depth_m: 10.0,
        floors: 4,
        ground_floor_m: 4.0,
        floor_m: 3.4,
        window_columns,
        window_m: [1.4, 1.7],
        sill_height_m: 0.9,
        recess_m: [0.15, 0.3],
        frame_width_m: 0.06,
        frame_protrusion_m: 0.04,
        door_column: window_columns / 2,
        roof_pitch_deg: 35.0,
        eave_m: 0.5,
        target_radius_m: 0.05,
        facade_material: Material::Brick,
    }
}

/// A hand-held station: aimed at `target`, then shaken by a few centimetres and about a degree.
fn station(rng: &mut Rng, centre: Vec3, target: Vec3) -> Pose {
    let centre = centre + Vec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.04;
    let aim = look_at(&centre, &target, &Vec3::z());
    let d = 0.6f64.to_radians();
    let shake = rotation_from_opk(rng.normal() * d, rng.normal() * d, rng.normal() * d);
    Pose {
        center: centre,
        rotation: shake * aim,
    }
}

/// The preset called `name`, with the hand-held jitter drawn from `seed`. `NAME@N` is preset `NAME`'s camera
/// set-up in front of building variant `N` ([`BuildingSpec::varied`]); `None` for an unknown name or a variant
/// that is not a number.
pub fn preset(name: &str, seed: u64) -> Option<Preset> {
    let (base, variant) = match name.split_once('@') {
        Some((base, n)) => (base, Some(n.parse::<u64>().ok()?)),
        None => (name, None),
    };
    let building = |width_m: f64, columns: u32| {
        let b = building(width_m, columns);
        variant.map_or_else(|| b.clone(), |v| b.varied(v))
    };
    let mut rng = Rng::new(seed, 2);
    let common = |_: &str, description, camera, building, poses| Preset {
        name: name.to_owned(),
        description,
        camera,
        building,
        poses,
        sensor: Sensor::default(),
        obs_sigma_px: 0.3,
        survey_sigma_m: 0.005,
    };
    Some(match base {
        "d2x-strip" => {
            // One strip of 33 at equal height, parallel to the façade at 19.3 m (GSD 5.9 mm), baseline 2.077 m.
            let b = building(60.0, 20);
            let poses = (0..33)
                .map(|i| {
                    let x = b.width_m / 2.0 + (i as f64 - 16.0) * 2.077;
                    station(
                        &mut rng,
                        Vec3::new(x, -19.3, 1.6),
                        Vec3::new(x, 0.0, 1.6 + 19.3 * 17f64.to_radians().tan()),
                    )
                })
                .collect();
            common(
                "d2x-strip",
                "Nikon D2X, one strip of 33 parallel to the facade at 19.3 m",
                d2x(),
                b,
                poses,
            )
        }
        "a55-two-strips" => {
            // Two strips of 9 at different heights, 25.1 m from the façade (GSD 6.7 mm), baseline 0.692 m.
            let b = building(30.0, 10);
            let poses = [1.5, 4.5]
                .iter()
                .flat_map(|&z| (0..9).map(move |i| (z, b.width_m / 2.0 + (i as f64 - 4.0) * 0.692)))
                .map(|(z, x)| {
                    station(
                        &mut rng,
                        Vec3::new(x, -25.1, z),
                        Vec3::new(x, 0.0, z + 25.1 * 14f64.to_radians().tan()),
                    )
                })
                .collect();
            common(
                "a55-two-strips",
                "Sony A55, two strips of 9 at 1.5 m and 4.5 m, 25.1 m from the facade",
                a55(),
                b,
                poses,
            )
        }
        "convergent" => {
            // An arc of 12 views around the façade centre, heading within ±25°.
            let b = building(30.0, 10);
            let aim = Vec3::new(b.width_m / 2.0, 0.0, 7.0);
            let poses = (0..12)
                .map(|i| {
                    let heading = (-25.0 + 50.0 * i as f64 / 11.0f64).to_radians();
                    let c = Vec3::new(aim.x + 20.0 * heading.sin(), -20.0 * heading.cos(), 1.6);
                    station(&mut rng, c, aim)
                })
                .collect();
            common(
                "convergent",
                "Nikon D2X, 12 views on an arc of 20 m radius, heading -25..25 deg",
                d2x(),
                b,
                poses,
            )
        }
        "roof" => {
            // Elevated oblique views (a lift or the building opposite) that see the eaves, verges and ridge.
            let b = building(30.0, 10);
            let z = b.wall_height_m() + 9.0;
            let poses = (0..10)
                .map(|i| {
                    let x = 3.0 + 24.0 * i as f64 / 9.0;
                    station(&mut rng, Vec3::new(x, -22.0, z), Vec3::new(x, 1.5, b.wall_height_m() - 4.0))
                })
                .collect();
            common(
                "roof",
                "Nikon D2X, 10 elevated oblique views 22 m out and 9 m above the eaves",
                d2x(),
                b,
                poses,
            )
        }
        _ => return None,
    })
}
