//! Task-space initialization of joint trajectories (the seed's `ik_interpolation`).

use armature_kinematics::Chain;
use armature_lie::SO3;
use nalgebra::Vector3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{IkError, IkResult, IkSettings, IkWorkspace, Target, solve};

/// A task-space keyframe at a node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Node index.
    pub node: usize,
    /// End-effector position (m).
    #[serde(deserialize_with = "armature_kinematics::exact::array")]
    pub position: [f64; 3],
    /// End-effector orientation `[w, x, y, z]`, or absent for position only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[serde(deserialize_with = "armature_kinematics::exact::optional")]
    pub quaternion_wxyz: Option<[f64; 4]>,
}

/// How nodes are seeded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Mode {
    /// Each node from the previous node's solution: a continuous joint path.
    Sequential,
    /// Every node from the same seed, solved concurrently (rayon).
    Parallel,
    /// The path of least travel over IK branches ([`crate::ik_branch_search`] from the seed,
    /// weighted by the inverse velocity limits where the chain has them): no branch jumps
    /// where a continuous path exists.
    Branches,
}

/// Joint trajectory from task-space keyframes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IkTrajectory {
    /// Joint values per node (N × n).
    pub q: Vec<Vec<f64>>,
    /// The solve at each node.
    pub nodes: Vec<IkResult>,
    /// Largest change of any joint between consecutive nodes (rad or m).
    pub max_joint_step: f64,
}

impl IkTrajectory {
    /// Whether every node converged.
    pub fn all_converged(&self) -> bool {
        self.nodes.iter().all(|r| r.converged)
    }
}

/// Largest node a keyframe may sit at: one IK solve per node, so this bounds the work an
/// input can ask for (100,000 nodes take seconds).
pub const MAX_KEYFRAME_NODE: usize = 100_000;

/// The interpolated targets at nodes `0..=last keyframe node`: positions linear and
/// orientations by slerp between consecutive keyframes (position-only where either end is
/// position-only); nodes before the first keyframe take its target.
///
/// # Errors
/// [`IkError::BadKeyframes`] for no keyframes, nodes not strictly increasing, non-finite
/// positions or non-unit quaternions.
pub fn interpolate_targets(keyframes: &[Keyframe]) -> Result<Vec<Target>, IkError> {
    let bad = |m: String| Err(IkError::BadKeyframes(m));
    if keyframes.is_empty() {
        return bad("no keyframes".into());
    }
    let mut targets = Vec::with_capacity(keyframes.len());
    for (i, k) in keyframes.iter().enumerate() {
        if k.node > MAX_KEYFRAME_NODE {
            return bad(format!(
                "keyframe {i}: node {} is beyond the largest node {MAX_KEYFRAME_NODE}",
                k.node
            ));
        }
        if i > 0 && k.node <= keyframes[i - 1].node {
            return bad(format!(
                "keyframe {i}: node {} does not come after node {}",
                k.node,
                keyframes[i - 1].node
            ));
        }
        let p = Vector3::from(k.position);
        let t = match k.quaternion_wxyz {
            Some(q) => Target::pose(p, q)
                .map_err(|e| IkError::BadKeyframes(format!("keyframe {i}: {e}")))?,
            None => Target::position(p),
        };
        if p.iter().any(|x| !x.is_finite()) {
            return bad(format!("keyframe {i}: position is not finite"));
        }
        targets.push(t);
    }
    let n_nodes = keyframes.last().map_or(0, |k| k.node) + 1;
    let mut out = vec![targets[0]; n_nodes];
    for w in 0..keyframes.len().saturating_sub(1) {
        let (a, b) = (keyframes[w].node, keyframes[w + 1].node);
        let (ta, tb) = (&targets[w], &targets[w + 1]);
        for (k, slot) in out.iter_mut().enumerate().take(b + 1).skip(a) {
            let s = (k - a) as f64 / (b - a) as f64;
            let orientation = match (ta.orientation, tb.orientation) {
                (Some(ra), Some(rb)) => Some(SO3::slerp(&ra, &rb, s)),
                _ => None,
            };
            *slot = Target { position: ta.position + (tb.position - ta.position) * s, orientation };
        }
    }
    Ok(out)
}

/// IK at every node of the interpolated keyframes, sequentially, in parallel or by the
/// branch search.
///
/// # Errors
/// As [`interpolate_targets`] and [`solve`] (bad seed or settings).
pub fn ik_interpolation(
    chain: &Chain,
    keyframes: &[Keyframe],
    seed: &[f64],
    settings: &IkSettings,
    mode: Mode,
) -> Result<IkTrajectory, IkError> {
    if mode == Mode::Branches {
        let weights: Vec<f64> =
            chain.joints().iter().map(|j| j.limits.velocity.map_or(1.0, |v| 1.0 / v)).collect();
        let (start, search) = (crate::Start::Seed(seed), crate::BranchSettings::default());
        let mut free = |_: usize, _: &[f64]| 0.0;
        return crate::ik_branch_search(
            chain, keyframes, start, settings, &search, &weights, &mut free,
        );
    }
    let targets = interpolate_targets(keyframes)?;
    let nodes: Vec<IkResult> = match mode {
        Mode::Sequential => {
            let mut ws = IkWorkspace::new(chain);
            let mut out: Vec<IkResult> = Vec::with_capacity(targets.len());
            // Warm starts keep the path continuous: restarts only when a warm start fails.
            let warm = IkSettings { restarts: 0, ..settings.clone() };
            for t in &targets {
                let from = out.last().map_or(seed, |r| r.q.as_slice());
                let mut r = solve(chain, t, from, &warm, &mut ws)?;
                if !r.converged && settings.restarts > 0 {
                    let retry = solve(chain, t, from, settings, &mut ws)?;
                    if retry.position_error + retry.orientation_error
                        < r.position_error + r.orientation_error
                    {
                        r = IkResult { iterations: r.iterations + retry.iterations, ..retry };
                    }
                }
                out.push(r);
            }
            out
        }
        Mode::Parallel | Mode::Branches => targets
            .par_iter()
            .map_init(|| IkWorkspace::new(chain), |ws, t| solve(chain, t, seed, settings, ws))
            .collect::<Result<_, _>>()?,
    };
    let q: Vec<Vec<f64>> = nodes.iter().map(|r| r.q.clone()).collect();
    let max_joint_step = q
        .windows(2)
        .flat_map(|w| w[0].iter().zip(&w[1]).map(|(a, b)| (a - b).abs()))
        .fold(0.0, f64::max);
    Ok(IkTrajectory { q, nodes, max_joint_step })
}
