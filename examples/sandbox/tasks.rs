//! Challenge tasks (RON files in assets/tasks) and their target poses.

use std::sync::Arc;

use bevy_wii_deform::deform::{
    ArapSolver, Constraints, InitialGuess, RigidTransform, SolveOptions, SolverSettings, Topology,
    TriMesh, centroid,
};
use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};

/// A vertex set, by geometry so a task survives regenerating the model.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub enum Region {
    /// Vertices whose coordinate along `axis` lies in `[from, to]` (fractions of the box).
    Slab { axis: usize, from: f64, to: f64 },
    /// Vertices within `radius` of `center` (model units).
    Sphere {
        center: (f64, f64, f64),
        radius: f64,
    },
    /// Vertices inside an axis-aligned box (model units).
    Box {
        min: (f64, f64, f64),
        max: (f64, f64, f64),
    },
    /// Explicit render vertex indices.
    Indices(Vec<u32>),
}

impl Region {
    /// Resolves to render vertex indices.
    pub fn resolve(&self, positions: &[DVec3]) -> Vec<u32> {
        match self {
            Region::Indices(v) => v
                .iter()
                .copied()
                .filter(|&i| (i as usize) < positions.len())
                .collect(),
            Region::Sphere { center, radius } => {
                let c = DVec3::new(center.0, center.1, center.2);
                (0..positions.len() as u32)
                    .filter(|&i| positions[i as usize].distance(c) <= *radius)
                    .collect()
            }
            Region::Box { min, max } => {
                let (lo, hi) = (
                    DVec3::new(min.0, min.1, min.2),
                    DVec3::new(max.0, max.1, max.2),
                );
                (0..positions.len() as u32)
                    .filter(|&i| {
                        let p = positions[i as usize];
                        p.cmpge(lo).all() && p.cmple(hi).all()
                    })
                    .collect()
            }
            Region::Slab { axis, from, to } => {
                let a = (*axis).min(2);
                let (mut lo, mut hi) = (f64::MAX, f64::MIN);
                for p in positions {
                    lo = lo.min(p[a]);
                    hi = hi.max(p[a]);
                }
                let span = (hi - lo).max(1e-12);
                (0..positions.len() as u32)
                    .filter(|&i| {
                        let t = (positions[i as usize][a] - lo) / span;
                        t >= *from && t <= *to
                    })
                    .collect()
            }
        }
    }
}

/// A posing task.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Task {
    pub name: String,
    pub model: String,
    pub fixed: Region,
    pub handle: Region,
    pub rotation_axis: (f64, f64, f64),
    pub rotation_degrees: f64,
    pub translation: (f64, f64, f64),
}

impl Task {
    /// Loads every `*.ron` task in `dir`, sorted by file name.
    pub fn load_all(dir: &str) -> Vec<(String, Task)> {
        let mut out = Vec::new();
        if let Ok(entries) = std::fs::read_dir(dir) {
            let mut paths: Vec<_> = entries.flatten().map(|e| e.path()).collect();
            paths.sort();
            for p in paths {
                if p.extension().and_then(|e| e.to_str()) != Some("ron") {
                    continue;
                }
                match std::fs::read_to_string(&p)
                    .map_err(|e| e.to_string())
                    .and_then(|t| ron::from_str::<Task>(&t).map_err(|e| e.to_string()))
                {
                    Ok(t) => out.push((
                        p.file_stem()
                            .unwrap_or_default()
                            .to_string_lossy()
                            .into_owned(),
                        t,
                    )),
                    Err(e) => eprintln!("skipping task {}: {e}", p.display()),
                }
            }
        }
        out
    }

    /// The handle's rigid motion (about its rest centroid).
    pub fn motion(&self, pivot: DVec3) -> RigidTransform {
        let axis = DVec3::new(
            self.rotation_axis.0,
            self.rotation_axis.1,
            self.rotation_axis.2,
        )
        .try_normalize()
        .unwrap_or(DVec3::Z);
        RigidTransform::new(
            DQuat::from_axis_angle(axis, self.rotation_degrees.to_radians()),
            DVec3::new(self.translation.0, self.translation.1, self.translation.2),
            pivot,
        )
    }

    /// Target pose (render order) computed by ARAP, converged.
    pub fn target_pose(&self, mesh: &TriMesh) -> Result<Vec<DVec3>, String> {
        let topology =
            Arc::new(Topology::new(&mesh.positions, &mesh.triangles).map_err(|e| e.to_string())?);
        let weld = |v: Vec<u32>| -> Vec<u32> {
            let mut w: Vec<u32> = v
                .iter()
                .map(|&i| topology.render_to_welded()[i as usize])
                .collect();
            w.sort_unstable();
            w.dedup();
            w
        };
        let fixed = weld(self.fixed.resolve(&mesh.positions));
        let handle: Vec<u32> = weld(self.handle.resolve(&mesh.positions))
            .into_iter()
            .filter(|v| fixed.binary_search(v).is_err())
            .collect();
        if handle.is_empty() {
            return Err(format!("task {:?}: empty handle region", self.name));
        }
        let pivot = centroid(topology.positions(), &handle);
        let c = Constraints::with_handle(fixed, handle, self.motion(pivot));
        let solver = ArapSolver::precompute(topology.clone(), &c, SolverSettings::default())
            .map_err(|e| e.to_string())?;
        let sol = solver
            .solve(
                &c,
                &SolveOptions {
                    max_iterations: 60,
                    tolerance: 1e-5,
                    ..Default::default()
                },
                InitialGuess::Laplacian,
                &|| false,
            )
            .map_err(|e| e.to_string())?;
        Ok(topology.to_render(&sol.positions))
    }
}

/// One completed challenge.
#[derive(Debug, Clone, PartialEq)]
pub struct ResultRow {
    pub task: String,
    pub input: String,
    pub seconds: f64,
}

/// Appends a result to the CSV (header on first write).
pub fn append_result(path: &str, row: &ResultRow) -> std::io::Result<()> {
    use std::io::Write;
    let new = !std::path::Path::new(path).exists();
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)?;
    if new {
        writeln!(f, "task,input,seconds")?;
    }
    writeln!(
        f,
        "{},{},{:.3}",
        row.task.replace(',', " "),
        row.input,
        row.seconds
    )
}

/// Reads all results from the CSV (malformed lines skipped).
pub fn read_results(path: &str) -> Vec<ResultRow> {
    let Ok(text) = std::fs::read_to_string(path) else {
        return Vec::new();
    };
    text.lines()
        .skip(1)
        .filter_map(|l| {
            let mut it = l.split(',');
            Some(ResultRow {
                task: it.next()?.to_string(),
                input: it.next()?.to_string(),
                seconds: it.next()?.trim().parse().ok()?,
            })
        })
        .collect()
}

/// One row of Table 1: task, mean seconds with the mouse, with a motion controller (any kind),
/// speed-up in %.
pub type SummaryRow = (String, Option<f64>, Option<f64>, Option<f64>);

/// Table 1: per task, mean seconds with the mouse and with motion controllers (every row that
/// is not the mouse's: `wiimote`, `dualsense`, …) and the controllers' speed-up in %.
pub fn summary(rows: &[ResultRow]) -> Vec<SummaryRow> {
    let mut tasks: Vec<String> = rows.iter().map(|r| r.task.clone()).collect();
    tasks.sort();
    tasks.dedup();
    tasks
        .into_iter()
        .map(|t| {
            let mean = |mouse: bool| {
                let v: Vec<f64> = rows
                    .iter()
                    .filter(|r| r.task == t && (r.input == "mouse") == mouse)
                    .map(|r| r.seconds)
                    .collect();
                (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
            };
            let (m, w) = (mean(true), mean(false));
            let speedup = match (m, w) {
                (Some(m), Some(w)) if m > 0.0 => Some((m - w) / m * 100.0),
                _ => None,
            };
            (t, m, w, speedup)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(task: &str, input: &str, seconds: f64) -> ResultRow {
        ResultRow {
            task: task.into(),
            input: input.into(),
            seconds,
        }
    }

    /// Rows name the controller's kind; the table puts every kind in the controller column
    /// and the mouse in its own.
    #[test]
    fn every_controller_kind_counts_as_a_controller_in_the_table() {
        let rows = [
            row("bend", "mouse", 10.0),
            row("bend", "mouse", 20.0),
            row("bend", "wiimote", 6.0),
            row("bend", "dualsense", 12.0),
            row("twist", "switch-pro", 4.0),
        ];
        let table = summary(&rows);
        assert_eq!(table.len(), 2);
        let (task, mouse, controller, speedup) = &table[0];
        assert_eq!(task, "bend");
        assert_eq!(*mouse, Some(15.0));
        assert_eq!(*controller, Some(9.0));
        assert!((speedup.unwrap() - 40.0).abs() < 1e-9);
        let (task, mouse, controller, speedup) = &table[1];
        assert_eq!(task, "twist");
        assert_eq!((*mouse, *controller, *speedup), (None, Some(4.0), None));
    }
}
