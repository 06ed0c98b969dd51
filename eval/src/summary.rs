//! The evaluation's figures as one JSON object (`metrics.json`, `lineflow eval --json`): what the report's tables
//! say, without the per-segment lists, for scripts and dashboards. Lengths in metres, shares from 0 to 1.
use serde_json::{json, Value};

use crate::geometry::stats;
use crate::model::ModelReport;
use crate::Evaluation;

/// The figures of `eval`; a part the results did not hold is `null`.
pub fn summary(eval: &Evaluation) -> Value {
    let orientation = eval.orientation.as_ref().map(|o| {
        json!({
            "images": o.images.len(),
            "missing": o.missing,
            "rms_center_m": o.rms_center_m,
            "max_center_m": o.max_center_m,
            "rms_rotation_deg": o.rms_rotation_deg,
            "max_rotation_deg": o.max_rotation_deg,
            "checkpoints": o.checkpoints.map(|(rmse, n)| json!({"rmse_m": rmse, "count": n})),
        })
    });
    let lines2d = eval
        .lines2d
        .as_ref()
        .map(|l| json!({ "images": l.images.len(), "recall": l.recall, "precision": l.precision }));
    let lines3d = eval.lines3d.as_ref().map(|l| {
        let (endpoint_mean, endpoint_std, endpoint_max) = stats(&l.endpoint_m);
        let (angle_mean, angle_std, angle_max) = stats(&l.angle_deg);
        let (long_mean, long_std, long_max) = stats(&l.angle_long_deg);
        let classes: Vec<Value> = l
            .classes
            .iter()
            .map(|c| {
                let at: Vec<Value> =
                    c.at.iter()
                        .map(|t| {
                            json!({
                                "label": t.label,
                                "tau_m": t.tau_m,
                                "segment_precision": t.segment_precision,
                                "length_precision": t.length_precision,
                                "length_recall": t.length_recall,
                                "surface_precision": t.surface_precision,
                            })
                        })
                        .collect();
                json!({
                    "class": c.class,
                    "true_edges": c.n_true,
                    "estimated": c.n_estimated,
                    "success_rate": c.success_rate,
                    "resolvable": c.n_resolvable,
                    "success_resolvable": c.success_resolvable,
                    "success_ceiling": c.success_ceiling,
                    "at": at,
                })
            })
            .collect();
        json!({
            "gsd_m": l.gsd_m,
            "estimated": l.estimated.len(),
            "true_edges": l.truth.len(),
            "matched": l.matched.iter().filter(|m| m.is_some()).count(),
            "endpoint_m": {"mean": endpoint_mean, "std": endpoint_std, "max": endpoint_max},
            "angle_deg": {"mean": angle_mean, "std": angle_std, "max": angle_max},
            "angle_long_deg": {"mean": long_mean, "std": long_std, "max": long_max},
            "classes": classes,
            "kinds": l.kinds().iter().map(|k| json!({
                "kind": k.kind,
                "edges": k.n_long,
                "found": k.n_found,
                "resolvable": k.n_resolvable,
                "found_resolvable": k.n_found_resolvable,
            })).collect::<Vec<Value>>(),
        })
    });
    let openings = eval.openings.as_ref().map(|o| {
        json!({
            "true": o.true_openings,
            "model": o.model_openings,
            "found": o.found,
            "kind_right": o.kind_right,
            "corner_rmse_m": o.corner_rmse_m,
            "reach_m": o.reach_m,
            "reveals_measured": o.reveals_measured,
            "reveals_right": o.reveals_right,
            "reveal_rmse_m": o.reveal_rmse_m,
            "reveal_tolerance_m": o.reveal_tolerance_m,
        })
    });
    json!({
        "orientation": orientation,
        "lines2d": lines2d,
        "lines3d": lines3d,
        "model": eval.model.as_ref().map(model),
        "model_fitted": eval.model_fitted.as_ref().map(model),
        "openings": openings,
        "hidden_edges": eval.hidden_edges,
        "surface_lines": eval.surface_lines.map(|s| json!({"lines": s.lines, "true_edges": s.true_edges})),
    })
}

fn model(m: &ModelReport) -> Value {
    json!({
        "true_vertices": m.true_vertices,
        "model_vertices": m.model_vertices,
        "matched_vertices": m.matched_vertices,
        "vertex_rmse_m": m.vertex_rmse_m,
        "true_edges": m.true_edges,
        "model_edges": m.model_edges,
        "edge_precision": m.edge_precision,
        "edge_recall": m.edge_recall,
        "unseen_edges": m.unseen_edges,
    })
}
