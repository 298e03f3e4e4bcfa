//! Candidate defaults applied to every task alike: a finer grid and settings overrides, so
//! that a change of default is judged on the whole suite before it is made.

use serde_json::Value;

use crate::generate::SuiteTask;

/// What a study changes in every task.
#[derive(Debug, Clone, Default)]
pub struct Study {
    /// Every task restated with this many intervals between consecutive waypoints, the
    /// integration's step length kept (`ArmTask::resegmented`; `None`: as generated, the
    /// dynamics model's default, 3 or 2).
    pub per_segment: Option<usize>,
    /// Every segment split into this many (1: the task as generated).
    pub subdivide: usize,
    /// Fields of `PtrSettings` to override, as a JSON object.
    pub settings: Option<Value>,
    /// Every task's velocity limits bounded at the integration grid's points or not
    /// (`ArmTask::velocity_limit_peaks`; `None`: each task's own default).
    pub velocity_peaks: Option<bool>,
    /// Every task's torques time-scaled or not (`ArmTask::time_scaled_torque`; `None`: each
    /// task's own default).
    pub time_scaled: Option<bool>,
    /// Mesh refinement: every task solved, then solved again on a grid this many times
    /// finer from that solution (1: once; `None`: each task's model's default,
    /// `DynamicsModel::default_refine`).
    pub refine: Option<usize>,
    /// Starts of every task's first solve (`Initialization::starts`; `None`: the task's own,
    /// the default 2).
    pub starts: Option<usize>,
    /// The rule by which every task's solve stops minimizing once its path retimed stalls
    /// (`ArmTask::retime_stall`; `None`: minimizing to the end).
    pub retime_stall: Option<armature_arm::RetimeStall>,
    /// Every task's IK sample seed (`Initialization::seed`; `None`: the task's own, 0).
    pub ik_seed: Option<u64>,
    /// Every task's fallback starts (`Initialization::fallbacks`; `None`: the default, 2).
    pub fallbacks: Option<usize>,
    /// Every task's IK samples per waypoint and restarts (`Initialization::restarts`; `None`:
    /// the task's own).
    pub ik_restarts: Option<usize>,
}

impl Study {
    /// From the command line's `--subdivide K`, `--refine K`, `--starts K`, `--settings JSON`
    /// and `--velocity-peaks true|false`.
    ///
    /// # Errors
    /// A subdivision, refinement or start count that is not a whole number from 1 to 16, settings that
    /// are not a JSON object, or velocity peaks that are neither `true` nor `false`.
    pub fn from_args(
        (subdivide, refine, starts): (Option<&String>, Option<&String>, Option<&String>),
        settings: Option<&String>,
        velocity_peaks: Option<&String>,
    ) -> Result<Self, String> {
        let factor = |flag: &str, k| count(flag, k).map(|k| k.unwrap_or(1));
        let subdivide = factor("--subdivide", subdivide)?;
        let refine = count("--refine", refine)?;
        let starts = count("--starts", starts)?;
        let settings = match settings {
            None => None,
            Some(s) => match serde_json::from_str::<Value>(s) {
                Ok(v @ Value::Object(_)) => Some(v),
                Ok(_) => return Err(format!("--settings {s}: need a JSON object")),
                Err(e) => return Err(format!("--settings {s}: {e}")),
            },
        };
        let velocity_peaks = switch("--velocity-peaks", velocity_peaks)?;
        Ok(Study {
            per_segment: None,
            subdivide,
            settings,
            velocity_peaks,
            time_scaled: None,
            refine,
            starts,
            retime_stall: None,
            ik_seed: None,
            fallbacks: None,
            ik_restarts: None,
        })
    }

    /// Every task's `ArmTask::retime_stall` when `on` (as the CLI's default for a retimed
    /// result): the default rule, or with `--retime-stall JSON` the default with the JSON
    /// object's fields; off, none.
    ///
    /// # Errors
    /// JSON that is not such an object, or a rule that is not valid.
    pub fn with_retime_stall(mut self, on: bool, json: Option<&String>) -> Result<Self, String> {
        self.retime_stall = None;
        if !on {
            return Ok(self);
        }
        let Some(json) = json else {
            self.retime_stall = Some(armature_arm::RetimeStall::default());
            return Ok(self);
        };
        let rule: armature_arm::RetimeStall =
            serde_json::from_str(json).map_err(|e| format!("--retime-stall {json}: {e}"))?;
        if !rule.is_valid() {
            return Err(format!("--retime-stall {json}: not a valid rule"));
        }
        self.retime_stall = Some(rule);
        Ok(self)
    }

    /// With the command line's `--time-scaled true|false` (none: each task's default).
    ///
    /// # Errors
    /// A value that is neither `true` nor `false`.
    pub fn with_time_scaled(mut self, on: Option<&String>) -> Result<Self, String> {
        self.time_scaled = switch("--time-scaled", on)?;
        Ok(self)
    }

    /// With the command line's `--ik-seed S` and `--fallbacks K` (none: each task's own).
    ///
    /// # Errors
    /// A value that is not a whole number (a fallback count from 0 to 16).
    pub fn with_starts_from(
        mut self,
        (seed, fallbacks, restarts): (Option<&String>, Option<&String>, Option<&String>),
    ) -> Result<Self, String> {
        if let Some(k) = restarts {
            match k.parse::<usize>() {
                Ok(k) if (1..=4096).contains(&k) => self.ik_restarts = Some(k),
                _ => return Err(format!("--ik-restarts {k}: need a whole number from 1 to 4096")),
            }
        }
        if let Some(s) = seed {
            self.ik_seed =
                Some(s.parse().map_err(|_| format!("--ik-seed {s}: need a whole number"))?);
        }
        if let Some(k) = fallbacks {
            match k.parse::<usize>() {
                Ok(k) if k <= 16 => self.fallbacks = Some(k),
                _ => return Err(format!("--fallbacks {k}: need a whole number from 0 to 16")),
            }
        }
        Ok(self)
    }

    /// With the command line's `--per-segment K` (none: the tasks as generated).
    ///
    /// # Errors
    /// A count that is not a whole number from 1 to 16.
    pub fn with_per_segment(mut self, k: Option<&String>) -> Result<Self, String> {
        self.per_segment = count("--per-segment", k)?;
        Ok(self)
    }

    /// The task with the study's changes.
    ///
    /// # Errors
    /// Settings that `PtrSettings` does not accept (an unknown key, a wrong type, or values
    /// its validation refuses), or a task that cannot be restated per segment, naming the
    /// task.
    pub fn apply(&self, mut t: SuiteTask) -> Result<SuiteTask, String> {
        if let Some(k) = self.per_segment {
            t.task = t.task.resegmented(k).map_err(|e| format!("{}: {e}", t.name))?;
        }
        if self.subdivide > 1 {
            t.task = t.task.subdivided(self.subdivide);
        }
        if let Some(k) = self.refine {
            t.refine = k;
        }
        if let Some(k) = self.starts {
            t.task.initialization.starts = k;
        }
        if let Some(seed) = self.ik_seed {
            t.task.initialization.seed = seed;
        }
        if let Some(k) = self.fallbacks {
            t.task.initialization.fallbacks = k;
        }
        if let Some(k) = self.ik_restarts {
            t.task.initialization.restarts = k;
        }
        if let Some(on) = self.velocity_peaks {
            t.task.velocity_limit_peaks = on;
        }
        if let Some(on) = self.time_scaled {
            t.task.time_scaled_torque = on;
        }
        t.task.retime_stall = self.retime_stall;
        if let Some(patch) = &self.settings {
            let mut current = serde_json::to_value(&t.task.settings).map_err(|e| e.to_string())?;
            merge(&mut current, patch);
            t.task.settings = serde_json::from_value(current)
                .map_err(|e| format!("{}: settings: {e}", t.name))?;
            t.task.settings.validate().map_err(|e| format!("{}: settings: {e}", t.name))?;
        }
        Ok(t)
    }
}

/// A `true|false` flag's value (`None` when not given).
fn switch(flag: &str, value: Option<&String>) -> Result<Option<bool>, String> {
    match value.map(String::as_str) {
        None => Ok(None),
        Some("true") => Ok(Some(true)),
        Some("false") => Ok(Some(false)),
        Some(v) => Err(format!("{flag} {v}: need true or false")),
    }
}

/// A flag's count: a whole number from 1 to 16, or `None` without the flag.
fn count(flag: &str, k: Option<&String>) -> Result<Option<usize>, String> {
    match k.map(|k| (k, k.parse::<usize>())) {
        None => Ok(None),
        Some((_, Ok(k @ 1..=16))) => Ok(Some(k)),
        Some((k, _)) => Err(format!("{flag} {k}: need a whole number from 1 to 16")),
    }
}

/// JSON merge patch (RFC 7386 without deletion): objects merge key by key, anything else
/// replaces.
fn merge(target: &mut Value, patch: &Value) {
    match (target, patch) {
        (Value::Object(t), Value::Object(p)) => {
            for (k, v) in p {
                merge(t.entry(k.clone()).or_insert(Value::Null), v);
            }
        }
        (t, p) => *t = p.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_merge_into_each_task_and_bad_ones_are_refused() {
        let task = crate::generate::suite().into_iter().next().expect("a task");
        let nodes = task.task.nodes;
        let study = Study::from_args(
            (Some(&"2".into()), Some(&"3".into()), Some(&"3".into())),
            Some(&r#"{"quasi_newton": true, "discretization": {"substeps": 7}}"#.into()),
            Some(&"false".into()),
        )
        .unwrap();
        let t = study.apply(task.clone()).unwrap();
        assert_eq!(t.task.nodes, 2 * (nodes - 1) + 1);
        assert_eq!((t.refine, task.refine), (3, 2));
        assert_eq!((t.task.initialization.starts, task.task.initialization.starts), (3, 2));
        assert!(!t.task.velocity_limit_peaks && task.task.velocity_limit_peaks);
        let own = Study::from_args((None, None, None), None, None).unwrap();
        assert!(own.apply(task.clone()).unwrap().task.velocity_limit_peaks);
        // Without `--refine` each task keeps its model's refinement.
        assert_eq!(own.apply(task.clone()).unwrap().refine, task.task.dynamics.default_refine());
        assert!(t.task.settings.quasi_newton);
        assert_eq!(t.task.settings.discretization.substeps, 7);
        // Untouched fields keep the task's value.
        assert_eq!(t.task.settings.max_iterations, task.task.settings.max_iterations);
        let bad = Study::from_args((None, None, None), Some(&r#"{"no_such_key": 1}"#.into()), None)
            .unwrap();
        assert!(bad.apply(task.clone()).unwrap_err().contains("no_such_key"));
        assert!(Study::from_args((Some(&"0".into()), None, None), None, None).is_err());
        assert!(Study::from_args((None, Some(&"17".into()), None), None, None).is_err());
        assert!(Study::from_args((None, None, Some(&"0".into())), None, None).is_err());
        assert!(Study::from_args((None, None, None), Some(&"[1]".into()), None).is_err());
        assert!(Study::from_args((None, None, None), None, Some(&"yes".into())).is_err());
    }

    #[test]
    fn the_retime_stall_rule_is_the_default_when_on_and_its_fields_can_change() {
        use armature_arm::RetimeStall;
        let task = crate::generate::suite().into_iter().next().expect("a task");
        let plain = || Study::from_args((None, None, None), None, None).unwrap();
        let on = plain().with_retime_stall(true, None).unwrap();
        assert_eq!(on.apply(task.clone()).unwrap().task.retime_stall, Some(RetimeStall::default()));
        let off = plain().with_retime_stall(false, Some(&"{}".into())).unwrap();
        assert_eq!(off.apply(task.clone()).unwrap().task.retime_stall, None);
        let wide = plain().with_retime_stall(true, Some(&r#"{"window": 6}"#.into())).unwrap();
        let rule = wide.apply(task).unwrap().task.retime_stall.unwrap();
        assert_eq!(rule, RetimeStall { window: 6, ..RetimeStall::default() });
        for bad in [r#"{"window": 0}"#, r#"{"no_such_key": 1}"#, "[1]"] {
            let e = plain().with_retime_stall(true, Some(&bad.into())).err().unwrap();
            assert!(e.contains("--retime-stall"), "{e}");
        }
    }

    #[test]
    fn every_task_can_be_restated_per_segment_and_bad_counts_are_refused() {
        let plain = || Study::from_args((None, None, None), None, None).unwrap();
        let three = plain().with_per_segment(Some(&"3".into())).unwrap();
        for task in crate::generate::suite().into_iter().filter(|t| !t.task.waypoints.is_empty()) {
            let t = three.apply(task.clone()).unwrap_or_else(|e| panic!("{e}"));
            let segments = task.task.waypoints.len() - 1;
            assert_eq!(t.task.nodes, 3 * segments + 1, "{}", task.name);
        }
        assert_eq!(plain().with_per_segment(None).unwrap().per_segment, None);
        for bad in ["0", "17", "two"] {
            let e = plain().with_per_segment(Some(&bad.into())).err().unwrap();
            assert!(e.contains("--per-segment"), "{e}");
        }
    }

    #[test]
    fn every_task_takes_the_ik_seed_fallbacks_and_restarts_given_and_bad_values_are_refused() {
        let plain = || Study::from_args((None, None, None), None, None).unwrap();
        let task = crate::generate::suite().into_iter().next().unwrap();
        let own =
            plain().with_starts_from((None, None, None)).unwrap().apply(task.clone()).unwrap();
        assert_eq!(own.task.initialization, task.task.initialization);
        let given = plain()
            .with_starts_from((Some(&"7".into()), Some(&"0".into()), Some(&"64".into())))
            .unwrap();
        let t = given.apply(task).unwrap();
        let i = t.task.initialization;
        assert_eq!((i.seed, i.fallbacks, i.restarts), (7, 0, 64));
        let e = plain().with_starts_from((Some(&"-1".into()), None, None)).err().unwrap();
        assert!(e.contains("--ik-seed"), "{e}");
        for bad in ["17", "x"] {
            let e = plain().with_starts_from((None, Some(&bad.into()), None)).err().unwrap();
            assert!(e.contains("--fallbacks"), "{e}");
        }
        for bad in ["0", "5000", "x"] {
            let e = plain().with_starts_from((None, None, Some(&bad.into()))).err().unwrap();
            assert!(e.contains("--ik-restarts"), "{e}");
        }
    }
}
