//! What the page receives: the result's dense trajectory (the series the view draws), its
//! status, the scene and the iterates — read from a result file or taken from a solve.

use std::collections::BTreeMap;

use armature_scvx::Solution;
use serde::{Deserialize, Serialize};

use super::Scene;

/// One SCvx iterate as the view draws it: the end effector at the nodes (iteration 0 is the
/// initial guess).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Iterate {
    /// Iteration number (0 = the guess).
    pub iteration: usize,
    /// Its final time (s).
    pub final_time: f64,
    /// End-effector position at each node (m).
    pub ee: Vec<[f64; 3]>,
}

/// The data embedded in the page.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewData {
    /// Where the result came from (a file name or a built-in example), for the title.
    #[serde(default)]
    pub source: String,
    /// The solver's status.
    pub status: String,
    /// Final time (s).
    pub final_time: f64,
    /// SCvx iterations.
    pub iterations: usize,
    /// The largest violation, as in the result.
    #[serde(default)]
    pub max_violation: Option<serde_json::Value>,
    /// The dense trajectory: `time` and the series the view draws.
    pub trajectory: BTreeMap<String, Vec<Vec<f64>>>,
    /// The task's geometry (absent for problem files).
    #[serde(default)]
    pub scene: Option<Scene>,
    /// The guess and the intermediate iterates, if the result holds them.
    #[serde(default)]
    pub iterates: Vec<Iterate>,
    /// A result file's retimed trajectory, read in place of the solve's own (not embedded).
    #[serde(default, skip_serializing)]
    pub retimed: Option<RetimedView>,
}

/// The part of a result file's `retimed` the view reads.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct RetimedView {
    /// Its final time (s).
    pub final_time: f64,
    /// Its samples.
    pub trajectory: BTreeMap<String, Vec<Vec<f64>>>,
}

/// The most samples a page embeds (see [`ViewData::thinned`]).
const MAX_SAMPLES: usize = 600;

/// Series the page reads when it has a scene (the keypoint frames come on top).
const SCENE_SERIES: [&str; 7] =
    ["time", "angle", "velocity", "torque", "ee_position", "ee_pose", "clearance"];

impl ViewData {
    /// The view of a solve's result.
    pub fn from_solution(
        source: &str,
        solution: &Solution,
        scene: Option<Scene>,
        iterates: Vec<Iterate>,
    ) -> ViewData {
        let data = ViewData {
            source: source.to_string(),
            status: solution.status.to_string(),
            final_time: solution.final_time,
            iterations: solution.iterations,
            max_violation: solution
                .max_violation
                .as_ref()
                .and_then(|v| serde_json::to_value(v).ok()),
            trajectory: solution.trajectory.clone(),
            scene,
            iterates,
            retimed: None,
        };
        data.pruned()
    }

    /// Reads a result file (the JSON of `armature solve -o`).
    ///
    /// # Errors
    /// `name:line:col: reason` when the text is not a result, or `name: reason` when its
    /// parts do not fit together (see [`check`](Self::check)).
    pub fn from_result_json(name: &str, text: &str) -> Result<ViewData, String> {
        if !text.trim_start().starts_with('{') {
            let skipped = &text[..text.len() - text.trim_start().len()];
            let line = skipped.matches('\n').count() + 1;
            let column = skipped.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            return Err(format!(
                "{name}:{line}:{column}: a result file is a JSON object, as `armature solve -o` writes it"
            ));
        }
        let mut data: ViewData = serde_json::from_str(text).map_err(|e| {
            let at = format!(" at line {} column {}", e.line(), e.column());
            let reason = e.to_string();
            format!("{name}:{}:{}: {}", e.line(), e.column(), reason.trim_end_matches(&at))
        })?;
        // A retimed result plays back as it is streamed: the retimed trajectory.
        if let Some(r) = data.retimed.take() {
            (data.final_time, data.trajectory) = (r.final_time, r.trajectory);
        }
        if data.source.is_empty() {
            data.source = name.to_string();
        }
        data.check().map_err(|e| format!("{name}: {e}"))?;
        Ok(data.pruned())
    }

    /// Keeps only the series the page draws when there is a scene (a problem file's
    /// result keeps every series: the page looks for frames among them).
    fn pruned(mut self) -> ViewData {
        if let Some(scene) = &self.scene {
            let keep: Vec<String> = SCENE_SERIES
                .iter()
                .map(|s| s.to_string())
                .chain(scene.keypoints.iter().map(|k| k.frame.clone()))
                .collect();
            self.trajectory.retain(|k, _| keep.contains(k));
        }
        self.thinned()
    }

    /// At most [`MAX_SAMPLES`] samples (a retimed trajectory has about 2500; the page plays
    /// a few hundred as smoothly): every `stride`-th, the last, and the closest approach
    /// (the smallest `clearance`, which `#t=closest` and the readout show).
    fn thinned(mut self) -> ViewData {
        let n = self.trajectory.get("time").map_or(0, Vec::len);
        if n <= MAX_SAMPLES {
            return self;
        }
        let stride = (n - 1).div_ceil(MAX_SAMPLES - 2);
        let closest = self.trajectory.get("clearance").and_then(|rows| {
            let smallest = |r: &Vec<f64>| r.iter().copied().fold(f64::INFINITY, f64::min);
            let each = rows.iter().map(smallest).enumerate();
            each.min_by(|a, b| a.1.total_cmp(&b.1)).map(|(i, _)| i)
        });
        let keep = |i: usize| i.is_multiple_of(stride) || i == n - 1 || Some(i) == closest;
        for rows in self.trajectory.values_mut() {
            let mut i = 0;
            rows.retain(|_| {
                i += 1;
                keep(i - 1)
            });
        }
        self
    }

    fn width(&self, series: &str) -> Option<usize> {
        self.trajectory.get(series).map(|rows| rows.first().map_or(0, Vec::len))
    }

    /// Checks that the parts fit: a `time` series, every series with one row per sample and
    /// rows of one width, scene indices in range, the frames and the clearance it names
    /// present with the right widths.
    ///
    /// # Errors
    /// What does not fit, naming the series, link or keypoint.
    pub fn check(&self) -> Result<(), String> {
        let samples = match self.trajectory.get("time") {
            Some(t) if !t.is_empty() && t.iter().all(|r| r.len() == 1) => t.len(),
            _ => return Err("the trajectory has no `time` series of one value per sample".into()),
        };
        for (name, rows) in &self.trajectory {
            if rows.len() != samples {
                return Err(format!("series `{name}` has {} rows, `time` {samples}", rows.len()));
            }
            if rows.iter().any(|r| r.len() != rows[0].len()) {
                return Err(format!("series `{name}` has rows of different widths"));
            }
        }
        let Some(scene) = &self.scene else { return Ok(()) };
        for k in &scene.keypoints {
            if self.width(&k.frame) != Some(16) {
                return Err(format!(
                    "keypoint `{}` needs a 4×4 frame series `{}` in the trajectory",
                    k.name, k.frame
                ));
            }
        }
        let n = scene.keypoints.len();
        if let Some(l) = scene.links.iter().find(|l| l.start >= n || l.end >= n) {
            return Err(format!(
                "link `{}` joins keypoints {} and {}; there are {n}",
                l.name, l.start, l.end
            ));
        }
        if let Some(c) = &scene.clearance
            && self.width("clearance") != Some(c.pairs.len())
        {
            return Err(format!(
                "the scene names {} collision pairs; the trajectory needs a `clearance` series of that width",
                c.pairs.len()
            ));
        }
        for (series, want) in [
            ("angle", scene.joints.len()),
            ("velocity", scene.joints.len()),
            ("torque", scene.joints.len()),
        ] {
            if let Some(w) = self.width(series).filter(|w| *w != want) {
                return Err(format!(
                    "series `{series}` has width {w}; the scene has {want} joints"
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_trajectory_is_thinned_keeping_its_ends_and_closest_approach() {
        let n = 2007;
        let time: Vec<Vec<f64>> = (0..n).map(|i| vec![i as f64 * 1e-3]).collect();
        let clearance: Vec<Vec<f64>> =
            (0..n).map(|i| vec![1.0, if i == 1001 { -0.5 } else { 0.1 }]).collect();
        let data = ViewData {
            source: String::new(),
            status: "converged".into(),
            final_time: 2.006,
            iterations: 1,
            max_violation: None,
            trajectory: [("time".to_string(), time), ("clearance".to_string(), clearance)]
                .into_iter()
                .collect(),
            scene: None,
            iterates: Vec::new(),
            retimed: None,
        }
        .thinned();
        let t = &data.trajectory["time"];
        assert!(t.len() <= MAX_SAMPLES && t.len() > MAX_SAMPLES / 2, "{}", t.len());
        assert_eq!(data.trajectory["clearance"].len(), t.len());
        assert_eq!(t[0][0], 0.0);
        assert_eq!(t[t.len() - 1][0], 2006.0 * 1e-3);
        assert!(t.iter().any(|r| r[0] == 1001.0 * 1e-3), "the closest approach is kept");
        assert!(data.trajectory["clearance"].iter().any(|r| r[1] == -0.5));
        // A short one is left alone.
        let short = ViewData { trajectory: data.trajectory.clone(), ..data.clone() }.thinned();
        assert_eq!(short.trajectory, data.trajectory);
    }
}
