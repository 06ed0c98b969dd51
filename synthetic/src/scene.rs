//! The procedural building: a façade with recessed windows (reveals, protruding frames with mullions and
//! transoms, glass), sills, a door, a balcony slab, a cornice, side walls, a gable roof with eaves, the ground,
//! and circular survey targets. Every structural edge is recorded as it is built.
use lineflow_photogrammetry::Vec3;
use serde::Serialize;

use super::geometry::{Edge, Face, Material};
use super::rng::Rng;

/// The parameters of a building. The façade is the plane Y = 0 (outward normal −Y), X along it, Z up.
#[derive(Debug, Clone, Serialize)]
pub struct BuildingSpec {
    /// Façade length along X, metres.
    pub width_m: f64,
    /// Building depth along +Y, metres.
    pub depth_m: f64,
    /// Storeys including the ground floor.
    pub floors: u32,
    /// Height of the ground floor, metres.
    pub ground_floor_m: f64,
    /// Height of each upper floor, metres.
    pub floor_m: f64,
    /// Window columns across the façade.
    pub window_columns: u32,
    /// Window opening width and height, metres.
    pub window_m: [f64; 2],
    /// Height of the window opening above its floor, metres.
    pub sill_height_m: f64,
    /// Range of the window recess (reveal depth to the glass), metres.
    pub recess_m: [f64; 2],
    /// Width of the window frame, mullion and transom, metres.
    pub frame_width_m: f64,
    /// How far the frame stands in front of the glass, metres.
    pub frame_protrusion_m: f64,
    /// Window column holding the door on the ground floor.
    pub door_column: u32,
    /// Roof pitch, degrees (gable roof, ridge along X).
    pub roof_pitch_deg: f64,
    /// Eave and verge overhang, metres.
    pub eave_m: f64,
    /// Radius of the white centre of a survey target, metres (the black ring has twice this radius).
    pub target_radius_m: f64,
    /// What the façade wall is made of (brick or plaster).
    pub facade_material: Material,
}

impl BuildingSpec {
    /// Another building for the same camera set-up: the façade keeps its length (so that the preset's stations
    /// still frame it) and everything else is drawn from `variant`: storeys and their heights, the window grid and
    /// the windows' size and sill, recesses from nearly flush to deep, frames, the door's bay, the roof and the
    /// wall's material. Thresholds tuned on the presets' one building meet these unseen; `lineflow bench` scores
    /// held-out variants that no test or tuning uses (`docs/synthetic.md`).
    pub fn varied(&self, variant: u64) -> BuildingSpec {
        let mut r = Rng::new(variant, 0xB0_11D1);
        let floor_m = r.uniform(2.8, 3.6);
        let sill_height_m = r.uniform(0.6, 1.1);
        let window_w = r.uniform(0.8, 1.8);
        // The door (1.2 m wide) shares a bay with the windows.
        let bay = r.uniform((window_w + 0.8).max(1.8), window_w + 2.6);
        let window_h = r.uniform(1.0, (floor_m - sill_height_m - 0.35).clamp(1.0, 2.2));
        let recess_m = match r.below(3) {
            0 => [0.03, 0.06],
            1 => [0.12, 0.25],
            _ => [0.3, 0.45],
        };
        let window_columns = ((self.width_m / bay).floor() as u32).max(2);
        BuildingSpec {
            width_m: self.width_m,
            depth_m: r.uniform(8.0, 14.0),
            floors: 2 + r.below(4) as u32,
            // Tall enough for the 2.4 m door and the balcony above it.
            ground_floor_m: floor_m + r.uniform(0.2, 1.2),
            floor_m,
            window_columns,
            window_m: [window_w, window_h],
            sill_height_m,
            recess_m,
            frame_width_m: r.uniform(0.04, 0.1),
            // The frame stands inside the recess.
            frame_protrusion_m: r.uniform(0.0, 0.05).min(recess_m[0] - 0.01),
            door_column: r.below(window_columns as usize) as u32,
            roof_pitch_deg: r.uniform(20.0, 45.0),
            eave_m: r.uniform(0.2, 0.8),
            target_radius_m: self.target_radius_m,
            facade_material: if r.below(2) == 0 { Material::Brick } else { Material::Plaster },
        }
    }

    /// Height of the façade wall (to the eave line), metres.
    pub fn wall_height_m(&self) -> f64 {
        self.ground_floor_m + (self.floors - 1) as f64 * self.floor_m + 0.8
    }
    /// Height of the ridge, metres.
    pub fn ridge_height_m(&self) -> f64 {
        self.wall_height_m() + self.depth_m / 2.0 * self.roof_pitch_deg.to_radians().tan()
    }
    fn floor_level(&self, floor: u32) -> f64 {
        if floor == 0 {
            0.0
        } else {
            self.ground_floor_m + (floor - 1) as f64 * self.floor_m
        }
    }
}

/// A survey target painted on a wall.
#[derive(Debug, Clone, Serialize)]
pub struct Target {
    /// Point id (C1.. for control, K1.. for check points).
    pub id: String,
    /// Centre, metres.
    pub xyz: [f64; 3],
    /// Surface the target is painted on.
    pub surface: u32,
    /// Used in the adjustment (otherwise a check point).
    pub control: bool,
}

/// The generated geometry.
#[derive(Debug, Clone, Serialize)]
pub struct Building {
    /// The parameters it was built from.
    pub spec: BuildingSpec,
    /// Every face.
    pub faces: Vec<Face>,
    /// Every structural edge (before any visibility test).
    pub edges: Vec<Edge>,
    /// Survey targets.
    pub targets: Vec<Target>,
    /// The true walls (façade, sides, back), counter-clockwise seen from outside.
    pub walls: Vec<(String, Vec<[f64; 3]>)>,
    /// The façade's openings: their outlines in the wall plane.
    pub openings: Vec<Opening>,
}

/// A window or door opening: its outline in the wall plane, counter-clockwise seen from outside.
#[derive(Debug, Clone, Serialize)]
pub struct Opening {
    /// A door (down to the ground floor), not a window.
    pub door: bool,
    /// Object coordinates, metres.
    pub corners: [[f64; 3]; 4],
    /// Depth of the reveal: from the wall's face back to the face of the window's frame or the door leaf, metres.
    pub reveal_m: f64,
}

/// A wall's own frame: `point(x, z, d) = origin + x·ex + z·ez − d·n` with n the outward normal.
#[derive(Debug, Clone, Copy)]
struct WallFrame {
    origin: Vec3,
    ex: Vec3,
    ez: Vec3,
    n: Vec3,
}

impl WallFrame {
    fn new(origin: Vec3, outward: Vec3) -> Self {
        let ez = Vec3::z();
        WallFrame {
            origin,
            ex: ez.cross(&outward),
            ez,
            n: outward,
        }
    }
    fn point(&self, x: f64, z: f64, depth: f64) -> Vec3 {
        self.origin + self.ex * x + self.ez * z - self.n * depth
    }
}

/// An axis-aligned rectangle in a wall frame: [x0, x1] × [z0, z1].
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rect {
    x0: f64,
    x1: f64,
    z0: f64,
    z1: f64,
}

impl Rect {
    fn new(x0: f64, x1: f64, z0: f64, z1: f64) -> Self {
        Rect { x0, x1, z0, z1 }
    }
    fn contains(&self, x: f64, z: f64) -> bool {
        x > self.x0 && x < self.x1 && z > self.z0 && z < self.z1
    }
    fn corners(&self) -> [(f64, f64); 4] {
        [(self.x0, self.z0), (self.x1, self.z0), (self.x1, self.z1), (self.x0, self.z1)]
    }
}

/// An opening in a relief face: a rectangular hole whose reveals run `depth` back to an inner relief.
struct Hole {
    rect: Rect,
    depth: f64,
    inner: Relief,
}

/// A planar face with rectangular holes, each leading back to another relief (or a plain face).
struct Relief {
    material: Material,
    holes: Vec<Hole>,
}

struct Builder {
    faces: Vec<Face>,
    edges: Vec<Edge>,
    next_surface: u32,
}

impl Builder {
    fn surface(&mut self) -> u32 {
        self.next_surface += 1;
        self.next_surface - 1
    }

    fn quad(&mut self, origin: Vec3, u: Vec3, v: Vec3, material: Material, surface: u32) {
        self.faces.push(Face {
            origin: origin.into(),
            u: u.into(),
            v: v.into(),
            triangle: false,
            material,
            surface,
        });
    }

    fn triangle(&mut self, a: Vec3, b: Vec3, c: Vec3, material: Material, surface: u32) {
        self.faces.push(Face {
            origin: a.into(),
            u: (b - a).into(),
            v: (c - a).into(),
            triangle: true,
            material,
            surface,
        });
    }

    fn edge(&mut self, a: Vec3, b: Vec3, kind: &'static str) {
        self.edges.push(Edge {
            a: a.into(),
            b: b.into(),
            kind,
        });
    }

    fn rect_edges(&mut self, w: &WallFrame, r: &Rect, depth: f64, kind: &'static str) {
        let c = r.corners();
        for i in 0..4 {
            let (a, b) = (c[i], c[(i + 1) % 4]);
            self.edge(w.point(a.0, a.1, depth), w.point(b.0, b.1, depth), kind);
        }
    }

    /// The relief at `depth` within `outline`: the face minus its holes, then each hole's reveals and inner relief.
    /// Records the edges of the holes; the outline's edges are the caller's business.
    fn relief(&mut self, w: &WallFrame, outline: Rect, depth: f64, relief: &Relief, kind: &'static str) -> u32 {
        let surface = self.surface();
        let holes: Vec<Rect> = relief.holes.iter().map(|h| h.rect).collect();
        for piece in decompose(&outline, &holes) {
            self.quad(
                w.point(piece.x0, piece.z0, depth),
                w.ex * (piece.x1 - piece.x0),
                w.ez * (piece.z1 - piece.z0),
                relief.material,
                surface,
            );
        }
        for hole in &relief.holes {
            let r = hole.rect;
            let back = depth + hole.depth;
            self.rect_edges(w, &r, depth, kind);
            // Reveals: the four side planes from the face back to the inner relief, each its own surface.
            let into = -w.n * hole.depth;
            let reveals = [
                (w.point(r.x0, r.z0, depth), into, w.ez * (r.z1 - r.z0)),
                (w.point(r.x1, r.z0, depth), w.ez * (r.z1 - r.z0), into),
                (w.point(r.x0, r.z0, depth), w.ex * (r.x1 - r.x0), into),
                (w.point(r.x0, r.z1, depth), into, w.ex * (r.x1 - r.x0)),
            ];
            for (o, u, v) in reveals {
                let s = self.surface();
                self.quad(o, u, v, relief.material, s);
            }
            for (x, z) in r.corners() {
                self.edge(w.point(x, z, depth), w.point(x, z, back), "reveal");
            }
            self.rect_edges(w, &r, back, kind);
            self.relief(w, r, back, &hole.inner, kind);
        }
        surface
    }

    /// A box standing out of a wall: `rect` on the wall, `out` metres in front of it. Back face omitted.
    fn slab(&mut self, w: &WallFrame, r: Rect, out: f64, material: Material, kind: &'static str) {
        let front = -out;
        let (dx, dz, dn) = (w.ex * (r.x1 - r.x0), w.ez * (r.z1 - r.z0), w.n * out);
        let faces = [
            (w.point(r.x0, r.z0, front), dx, dz),
            (w.point(r.x0, r.z1, 0.0), dx, dn),
            (w.point(r.x0, r.z0, 0.0), dn, dx),
            (w.point(r.x0, r.z0, 0.0), dz, dn),
            (w.point(r.x1, r.z0, 0.0), dn, dz),
        ];
        for (o, u, v) in faces {
            let s = self.surface();
            self.quad(o, u, v, material, s);
        }
        self.rect_edges(w, &r, front, kind);
        self.rect_edges(w, &r, 0.0, kind);
        for (x, z) in r.corners() {
            self.edge(w.point(x, z, 0.0), w.point(x, z, front), kind);
        }
    }
}

/// Splits `outline` minus the (disjoint) `holes` into rectangles along a grid of their coordinates.
fn decompose(outline: &Rect, holes: &[Rect]) -> Vec<Rect> {
    let mut xs = vec![outline.x0, outline.x1];
    let mut zs = vec![outline.z0, outline.z1];
    for h in holes {
        xs.extend([h.x0, h.x1]);
        zs.extend([h.z0, h.z1]);
    }
    for v in [&mut xs, &mut zs] {
        v.sort_by(f64::total_cmp);
        v.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    }
    let mut out = Vec::new();
    for zw in zs.windows(2) {
        let mut run: Option<f64> = None;
        for xw in xs.windows(2) {
            let (cx, cz) = ((xw[0] + xw[1]) / 2.0, (zw[0] + zw[1]) / 2.0);
            let solid = !holes.iter().any(|h| h.contains(cx, cz));
            match (solid, run) {
                (true, None) => run = Some(xw[0]),
                (false, Some(x0)) => {
                    out.push(Rect::new(x0, xw[0], zw[0], zw[1]));
                    run = None;
                }
                _ => {}
            }
        }
        if let Some(x0) = run {
            out.push(Rect::new(x0, *xs.last().unwrap_or(&x0), zw[0], zw[1]));
        }
    }
    out
}

fn glass() -> Relief {
    Relief {
        material: Material::Glass,
        holes: Vec::new(),
    }
}

/// A window: frame face at the front of the recess, four panes (mullion and transom) set back to the glass.
fn window(spec: &BuildingSpec, opening: Rect, recess: f64) -> Hole {
    let fw = spec.frame_width_m;
    let xm = (opening.x0 + opening.x1) / 2.0;
    let zt = opening.z1 - fw - 0.45;
    let mut panes = Vec::new();
    for (x0, x1) in [(opening.x0 + fw, xm - fw / 2.0), (xm + fw / 2.0, opening.x1 - fw)] {
        for (z0, z1) in [(opening.z0 + fw, zt - fw / 2.0), (zt + fw / 2.0, opening.z1 - fw)] {
            panes.push(Hole {
                rect: Rect::new(x0, x1, z0, z1),
                depth: spec.frame_protrusion_m,
                inner: glass(),
            });
        }
    }
    Hole {
        rect: opening,
        depth: recess - spec.frame_protrusion_m,
        inner: Relief {
            material: Material::Frame,
            holes: panes,
        },
    }
}

fn door(opening: Rect) -> Hole {
    let pane = Rect::new(opening.x0 + 0.18, opening.x1 - 0.18, opening.z1 - 1.0, opening.z1 - 0.2);
    Hole {
        rect: opening,
        depth: 0.22,
        inner: Relief {
            material: Material::Wood,
            holes: vec![Hole {
                rect: pane,
                depth: 0.03,
                inner: glass(),
            }],
        },
    }
}

/// Builds the building of `spec`; `seed` varies the window recesses and picks the check points.
pub fn build(spec: &BuildingSpec, seed: u64) -> Building {
    let mut rng = Rng::new(seed, 1);
    let mut b = Builder {
        faces: Vec::new(),
        edges: Vec::new(),
        next_surface: 0,
    };
    let (w, d, h) = (spec.width_m, spec.depth_m, spec.wall_height_m());
    let pitch = spec.roof_pitch_deg.to_radians().tan();
    let ridge = spec.ridge_height_m();
    let facade = WallFrame::new(Vec3::zeros(), -Vec3::y());
    let spacing = w / spec.window_columns as f64;
    let [ww, wh] = spec.window_m;

    // Façade openings.
    let mut holes = Vec::new();
    let mut sills = Vec::new();
    let mut door_rect = None;
    for floor in 0..spec.floors {
        for col in 0..spec.window_columns {
            let xc = (col as f64 + 0.5) * spacing;
            if floor == 0 && col == spec.door_column {
                let r = Rect::new(xc - 0.6, xc + 0.6, 0.12, 2.4);
                door_rect = Some(r);
                holes.push(door(r));
                continue;
            }
            let z0 = spec.floor_level(floor) + spec.sill_height_m;
            let r = Rect::new(xc - ww / 2.0, xc + ww / 2.0, z0, z0 + wh);
            holes.push(window(spec, r, rng.uniform(spec.recess_m[0], spec.recess_m[1])));
            sills.push(Rect::new(r.x0 - 0.05, r.x1 + 0.05, z0 - 0.09, z0 - 0.03));
        }
    }
    let openings = holes
        .iter()
        .map(|h: &Hole| {
            let r = &h.rect;
            let corner = |x: f64, z: f64| facade.point(x, z, 0.0).into();
            Opening {
                door: door_rect == Some(*r),
                corners: [corner(r.x0, r.z0), corner(r.x1, r.z0), corner(r.x1, r.z1), corner(r.x0, r.z1)],
                reveal_m: h.depth,
            }
        })
        .collect();
    let facade_relief = Relief {
        material: spec.facade_material,
        holes,
    };
    let outline = Rect::new(0.0, w, 0.0, h);
    let facade_surface = b.relief(&facade, outline, 0.0, &facade_relief, "opening");
    b.rect_edges(&facade, &outline, 0.0, "outline");
    for s in sills {
        b.slab(&facade, s, 0.06, Material::Stone, "sill");
    }
    b.slab(
        &facade,
        Rect::new(-0.2, w + 0.2, h - 0.75, h - 0.55),
        0.25,
        Material::Stone,
        "cornice",
    );
    if let Some(r) = door_rect {
        let level = spec.floor_level(1);
        let xc = (r.x0 + r.x1) / 2.0;
        b.slab(
            &facade,
            Rect::new(xc - 2.0, xc + 2.0, level - 0.2, level),
            1.2,
            Material::Stone,
            "balcony",
        );
    }

    // Side walls with their gables, one plastered surface each; the façade corner edges are already recorded.
    // `back` is the wall coordinate of the building's back corner.
    for (origin, outward, back) in [(Vec3::new(0.0, d, 0.0), -Vec3::x(), 0.0), (Vec3::new(w, 0.0, 0.0), Vec3::x(), d)] {
        let side = WallFrame::new(origin, outward);
        let s = b.surface();
        b.quad(side.point(0.0, 0.0, 0.0), side.ex * d, side.ez * h, Material::Plaster, s);
        b.triangle(
            side.point(0.0, h, 0.0),
            side.point(d, h, 0.0),
            side.point(d / 2.0, ridge, 0.0),
            Material::Plaster,
            s,
        );
        b.edge(side.point(0.0, 0.0, 0.0), side.point(d, 0.0, 0.0), "outline");
        b.edge(side.point(back, 0.0, 0.0), side.point(back, h, 0.0), "outline");
        b.edge(side.point(0.0, h, 0.0), side.point(d / 2.0, ridge, 0.0), "roof");
        b.edge(side.point(d, h, 0.0), side.point(d / 2.0, ridge, 0.0), "roof");
    }

    // Gable roof: two slopes from the eaves to the ridge, overhanging the walls, with fascia boards.
    let e = spec.eave_m;
    let run = d / 2.0 + e;
    let eave_z = h - e * pitch;
    let along = Vec3::new(w + 2.0 * e, 0.0, 0.0);
    for (eave_y, dir) in [(-e, 1.0), (d + e, -1.0)] {
        let eave = Vec3::new(-e, eave_y, eave_z);
        let up = Vec3::new(0.0, dir * run, run * pitch);
        let s = b.surface();
        b.quad(eave, along, up, Material::Tiles, s);
        let fascia = b.surface();
        b.quad(eave - Vec3::z() * 0.2, along, Vec3::z() * 0.2, Material::Frame, fascia);
        b.edge(eave, eave + along, "roof");
        b.edge(eave - Vec3::z() * 0.2, eave + along - Vec3::z() * 0.2, "roof");
        b.edge(eave, eave + up, "roof");
        b.edge(eave + along, eave + along + up, "roof");
    }
    b.edge(Vec3::new(-e, d / 2.0, ridge), Vec3::new(w + e, d / 2.0, ridge), "roof");

    // The ground.
    let g = b.surface();
    b.quad(
        Vec3::new(-80.0, -100.0, 0.0),
        Vec3::new(w + 160.0, 0.0, 0.0),
        Vec3::new(0.0, d + 160.0, 0.0),
        Material::Asphalt,
        g,
    );

    let targets = place_targets(spec, facade_surface, &mut rng);
    let corner = |x: f64, y: f64, z: f64| [x, y, z];
    let walls = vec![
        (
            "facade".to_string(),
            vec![corner(0.0, 0.0, 0.0), corner(w, 0.0, 0.0), corner(w, 0.0, h), corner(0.0, 0.0, h)],
        ),
        (
            "east".to_string(),
            vec![corner(w, 0.0, 0.0), corner(w, d, 0.0), corner(w, d, h), corner(w, 0.0, h)],
        ),
        (
            "back".to_string(),
            vec![corner(w, d, 0.0), corner(0.0, d, 0.0), corner(0.0, d, h), corner(w, d, h)],
        ),
        (
            "west".to_string(),
            vec![corner(0.0, d, 0.0), corner(0.0, 0.0, 0.0), corner(0.0, 0.0, h), corner(0.0, d, h)],
        ),
    ];
    Building {
        spec: spec.clone(),
        faces: b.faces,
        edges: b.edges,
        targets,
        walls,
        openings,
    }
}

/// Targets on the brick piers between window columns, at mid-window height of each floor: the four outermost
/// as control points, then up to 26 check points (as many as the thesis had) chosen by the seed.
fn place_targets(spec: &BuildingSpec, surface: u32, rng: &mut Rng) -> Vec<Target> {
    let spacing = spec.width_m / spec.window_columns as f64;
    let mut spots = Vec::new();
    for floor in 0..spec.floors {
        let z = spec.floor_level(floor) + spec.sill_height_m + spec.window_m[1] / 2.0;
        for col in 1..spec.window_columns {
            spots.push([col as f64 * spacing, z]);
        }
    }
    let (xmin, xmax) = (spacing, (spec.window_columns - 1) as f64 * spacing);
    let (zmin, zmax) = spots
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| (a.min(s[1]), b.max(s[1])));
    let corners = [[xmin, zmin], [xmax, zmin], [xmax, zmax], [xmin, zmax]];
    let mut targets: Vec<Target> = corners
        .iter()
        .enumerate()
        .map(|(i, c)| Target {
            id: format!("C{}", i + 1),
            xyz: [c[0], 0.0, c[1]],
            surface,
            control: true,
        })
        .collect();
    spots.retain(|s| !corners.contains(s));
    // A seeded partial shuffle keeps the choice deterministic.
    for i in 0..spots.len() {
        let j = i + (rng.next_u64() % (spots.len() - i) as u64) as usize;
        spots.swap(i, j);
    }
    spots.truncate(26);
    spots.sort_by(|a, b| a[1].total_cmp(&b[1]).then(a[0].total_cmp(&b[0])));
    for (i, s) in spots.iter().enumerate() {
        targets.push(Target {
            id: format!("K{}", i + 1),
            xyz: [s[0], 0.0, s[1]],
            surface,
            control: false,
        });
    }
    targets
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_variant_is_another_building_of_the_same_length_and_the_same_on_every_draw() {
        let base = crate::preset("a55-two-strips", 1).unwrap().building;
        let v = base.varied(1);
        assert_eq!(v.width_m, base.width_m);
        assert_eq!(format!("{v:?}"), format!("{:?}", base.varied(1)));
        let all: Vec<BuildingSpec> = (1..40).map(|n| base.varied(n)).collect();
        assert!(all.iter().any(|b| b.recess_m[1] < 0.1) && all.iter().any(|b| b.recess_m[0] >= 0.3));
        assert!(all.iter().any(|b| b.facade_material == Material::Plaster));
        for b in &all {
            let bay = b.width_m / b.window_columns as f64;
            assert!(bay >= 1.6 && b.window_m[0] < bay, "{b:?}");
            assert!(b.sill_height_m + b.window_m[1] <= b.floor_m - 0.3, "{b:?}");
            assert!(b.ground_floor_m >= 3.0 && b.frame_protrusion_m < b.recess_m[0], "{b:?}");
            assert!(!build(b, 1).edges.is_empty());
        }
    }

    #[test]
    fn a_variant_is_named_after_its_preset_and_a_bad_one_is_refused() {
        let p = crate::preset("d2x-strip@1001", 1).unwrap();
        assert_eq!(p.name, "d2x-strip@1001");
        assert_eq!(p.poses.len(), 33);
        assert!(crate::preset("d2x-strip@x", 1).is_none());
        assert!(crate::preset("nowhere@3", 1).is_none());
    }

    #[test]
    fn decomposition_covers_the_outline_minus_the_holes() {
        let outline = Rect::new(0.0, 10.0, 0.0, 5.0);
        let holes = [Rect::new(1.0, 2.0, 1.0, 3.0), Rect::new(5.0, 7.0, 2.0, 4.0)];
        let pieces = decompose(&outline, &holes);
        let area: f64 = pieces.iter().map(|r| (r.x1 - r.x0) * (r.z1 - r.z0)).sum();
        assert!((area - (50.0 - 2.0 - 4.0)).abs() < 1e-9);
        for p in &pieces {
            let (cx, cz) = ((p.x0 + p.x1) / 2.0, (p.z0 + p.z1) / 2.0);
            assert!(!holes.iter().any(|h| h.contains(cx, cz)));
        }
    }
}
