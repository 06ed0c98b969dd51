//! The fitted wire-frame as a [`Model`] with the model stage's faces, so that `model_fitted.obj` and
//! `model_fitted.city.json` are written by the same code as `model.obj` and `model.city.json`. The fit moves
//! vertices only; the faces (rings of vertex indices, from the `faces` topic) hold as they are.
use lineflow_messages::{FaceVertex, WireEdge};
use lineflow_model::{Edge, EdgeOrigin, Face, Model, SurfaceKind, Vertex};
use lineflow_photogrammetry::{polygon_normal, Vec3};

/// The model of `vertices` and `edges` with the faces of `faces` (rings in order, outer ring 0 first, then the
/// holes); an error names a face that does not fit the wire-frame.
pub fn fitted_model(vertices: &[Vec3], edges: &[WireEdge], faces: &[FaceVertex]) -> Result<Model, String> {
    let mut model = Model {
        vertices: vertices.iter().map(|&point| Vertex { point, sigma: None }).collect(),
        edges: edges
            .iter()
            .map(|e| Edge {
                a: e.a as usize,
                b: e.b as usize,
                line: usize::MAX,
                origin: if e.hidden != 0 { EdgeOrigin::Hidden } else { EdgeOrigin::Observed },
            })
            .collect(),
        ..Model::default()
    };
    // Consecutive rows of one face, then of one ring.
    for face in faces.chunk_by(|a, b| a.face == b.face) {
        let f = face[0].face;
        let kind = SurfaceKind::from_code(face[0].kind).ok_or_else(|| format!("face {f}: unknown kind code {}", face[0].kind))?;
        let mut rings: Vec<Vec<usize>> = Vec::new();
        for ring in face.chunk_by(|a, b| a.ring == b.ring) {
            if ring[0].ring as usize != rings.len() {
                return Err(format!("face {f}: ring {} out of order", ring[0].ring));
            }
            if ring.len() < 3 {
                return Err(format!("face {f}: a ring of {} vertices", ring.len()));
            }
            if let Some(v) = ring.iter().find(|v| v.vertex as usize >= vertices.len()) {
                return Err(format!("face {f}: vertex {} beyond the wire-frame's {}", v.vertex, vertices.len()));
            }
            rings.push(ring.iter().map(|v| v.vertex as usize).collect());
        }
        let ring = rings.remove(0);
        model.faces.push(Face {
            normal: polygon_normal(&ring.iter().map(|&v| vertices[v]).collect::<Vec<_>>()).unwrap_or_default(),
            ring,
            holes: rings,
            kind,
        });
    }
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(face: u32, ring: u32, kind: u32, vertex: u32) -> FaceVertex {
        FaceVertex { face, ring, kind, vertex }
    }

    #[test]
    fn a_wall_with_an_opening_keeps_its_rings_and_gets_the_fitted_vertices() {
        // A 4 × 3 wall in the plane y = 0 with a window, the vertices moved by a fit.
        let v: Vec<Vec3> = [
            [0., 0., 0.],
            [4., 0., 0.],
            [4., 0., 3.],
            [0., 0., 3.],
            [1., 0., 1.],
            [2., 0., 1.],
            [2., 0., 2.],
            [1., 0., 2.],
        ]
        .iter()
        .map(|p| Vec3::new(p[0] + 0.001, p[1], p[2]))
        .collect();
        let edges: Vec<WireEdge> = (0..4)
            .map(|i| [i, (i + 1) % 4])
            .chain((0..4).map(|i| [4 + i, 4 + (i + 1) % 4]))
            .map(|[a, b]| WireEdge {
                a,
                b,
                ..WireEdge::default()
            })
            .collect();
        let mut rows: Vec<FaceVertex> = (0..4).map(|i| row(0, 0, 0, i)).collect();
        rows.extend((4..8).rev().map(|i| row(0, 1, 0, i)));
        rows.extend((4..8).map(|i| row(1, 0, 4, i)));
        let m = fitted_model(&v, &edges, &rows).unwrap();
        assert_eq!(m.faces.len(), 2);
        assert_eq!(m.faces[0].ring, vec![0, 1, 2, 3]);
        assert_eq!(m.faces[0].holes, vec![vec![7, 6, 5, 4]]);
        assert_eq!((m.faces[0].kind, m.faces[1].kind), (SurfaceKind::Wall, SurfaceKind::Window));
        assert!((m.faces[0].normal.y.abs() - 1.0).abs() < 1e-9, "{:?}", m.faces[0].normal);
        assert_eq!(m.vertices[1].point, v[1]);
        assert_eq!(m.edges.len(), 8);
        let obj = lineflow_model::export::obj_text(&m);
        assert!(obj.contains("g WallSurface\nf 1 2 3 4\n") && obj.contains("g Window\n"), "{obj}");
    }

    #[test]
    fn faces_that_do_not_fit_the_wire_frame_are_refused_with_a_reason() {
        let v = vec![Vec3::zeros(); 3];
        let bad_vertex = [row(0, 0, 0, 0), row(0, 0, 0, 1), row(0, 0, 0, 9)];
        assert!(fitted_model(&v, &[], &bad_vertex).unwrap_err().contains("vertex 9"));
        let bad_kind = [row(0, 0, 17, 0), row(0, 0, 17, 1), row(0, 0, 17, 2)];
        assert!(fitted_model(&v, &[], &bad_kind).unwrap_err().contains("kind"));
        let short = [row(0, 0, 0, 0), row(0, 0, 0, 1)];
        assert!(fitted_model(&v, &[], &short).unwrap_err().contains("ring of 2"));
        assert!(fitted_model(&v, &[], &[]).unwrap().faces.is_empty());
    }
}
