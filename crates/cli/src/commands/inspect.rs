//! `armature inspect`: what a task compiles to, without solving.

use std::fmt::Write as _;
use std::path::PathBuf;

use armature_scvx::NodalKind;
use clap::Args;

use super::solve::{Loaded, load};
use crate::task::Source;
use crate::{CliError, exit};

/// Arguments of `armature inspect`.
#[derive(Debug, Clone, Args)]
pub struct InspectArgs {
    /// The task or problem file (TOML).
    pub file: PathBuf,
}

/// Runs `armature inspect`: the robot, nodes and waypoints, the states and controls with
/// their bounds, every constraint with its kind and nodes, the Jacobian sparsity of the
/// dynamics and of the discretized matrices, and the subproblem's dimensions.
///
/// # Errors
/// Bad input (as `armature solve`), output failures.
pub fn run(args: &InspectArgs, out: &mut dyn std::io::Write) -> Result<(), CliError> {
    let text = crate::read_input(&args.file)?;
    let name = args.file.display().to_string();
    let src = Source { name: &name, text: &text };
    let Loaded { plan, mut compiled, refined, starts, .. } = load(src, Some(&args.file))?;
    let mut s = String::new();
    if let Some(plan) = &plan {
        let chain = &plan.chain;
        let _ = writeln!(
            s,
            "robot {}: {} joints, keypoints {}",
            chain.name(),
            chain.dof(),
            chain.keypoint_names().collect::<Vec<_>>().join(", ")
        );
        let _ = writeln!(s, "nodes: {} ({} segments)", plan.nodes, plan.nodes - 1);
        if let Some((factor, fine, _)) = &refined {
            let _ = writeln!(
                s,
                "  then refined: {} nodes, every segment split in {factor} (`[nodes] refine`; what follows is the first stage)",
                fine.nodes
            );
        }
        for w in &plan.waypoints {
            let _ = writeln!(
                s,
                "  waypoint {:<12} node {:>3}  position {:?} ± {} m",
                w.name, w.node, w.position, w.tolerance
            );
        }
        let ik_ok = plan.ik.nodes.iter().filter(|r| r.converged).count();
        let _ = writeln!(
            s,
            "initial guess: IK {ik_ok}/{} nodes converged, spline duration {:.4} s",
            plan.nodes,
            plan.dilation_guess[..plan.nodes - 1].iter().sum::<f64>() / (plan.nodes - 1) as f64
        );
        if let Some((count, task)) = &starts {
            let samples: Vec<String> = (0..*count)
                .map(|i| {
                    armature_arm::start_ik_samples(task.initialization.restarts, i).to_string()
                })
                .collect();
            let _ = writeln!(
                s,
                "starts: {count}, solved side by side from the IK paths searched with {} random configurations per waypoint (`[initialization] starts`; the guess above is the first start's)",
                samples.join(", ")
            );
        }
    } else {
        let nodes = compiled.ptr().ocp().nodes;
        let _ = writeln!(s, "problem file: {nodes} nodes ({} segments)", nodes - 1);
    }
    let ocp = compiled.ptr().ocp().clone();
    let d = &ocp.dynamics;
    let _ = writeln!(s, "\nstates ({}):", d.n_x());
    for i in 0..d.n_x() {
        let fixed = |v: Option<f64>| v.map_or("free".to_string(), |v| format!("{v:.4}"));
        let _ = writeln!(
            s,
            "  {:<14} [{:>9.4}, {:>9.4}]  initial {:<8} final {}",
            d.state_name(i).unwrap_or("?"),
            ocp.x_min[i],
            ocp.x_max[i],
            fixed(ocp.x_initial[i]),
            fixed(ocp.x_final[i])
        );
    }
    let _ = writeln!(s, "controls ({}): bounds {:?} … {:?}", d.n_u(), ocp.u_min, ocp.u_max);
    let _ = writeln!(
        s,
        "time: dilation per segment in [{}, {}], final time in [{}, {}], time weight {}",
        ocp.s_min, ocp.s_max, ocp.final_time.0, ocp.final_time.1, ocp.time_weight
    );
    let _ = writeln!(s, "\ncontinuous-time constraints (CTCS integrals, nodal increments ≤ ε):");
    for (internal, what) in compiled.ctcs_groups() {
        let _ = writeln!(s, "  {:<8} {what}", internal);
    }
    let _ = writeln!(s, "nodal constraints:");
    for c in &ocp.nodal {
        let kind = match c.kind {
            NodalKind::Inequality => {
                format!("g ≤ 0 ({} entries, linearized)", c.function.n_outputs())
            }
            NodalKind::Ball { radius } => format!("‖g‖ ≤ {radius:.6} (second-order cone)"),
        };
        let _ = writeln!(s, "  {:<48} {kind}, nodes {:?}", c.name, c.nodes);
    }
    between_nodes(&mut s, &ocp);
    let jac = d.function().jacobian_pattern();
    let _ = writeln!(
        s,
        "\ndynamics Jacobian ∂f/∂[x, u]: {}×{}, {} nonzeros",
        jac.nrows(),
        jac.ncols(),
        jac.nnz()
    );
    let _ = write!(s, "{jac}");
    let tp = d.transition_pattern();
    let _ = writeln!(
        s,
        "discretized [A | B | s] per segment: {}×{}, {} structural nonzeros (of {})",
        tp.nrows(),
        tp.ncols(),
        tp.nnz(),
        tp.nrows() * tp.ncols()
    );
    let _ = write!(s, "{tp}");
    let dims = compiled.ptr().dimensions();
    let _ = writeln!(
        s,
        "\nsubproblem: {} variables; {} equality, {} inequality rows; {} second-order cones ({} rows); {} nonzeros in A, {} in P (upper triangle)",
        dims.variables,
        dims.equality_rows,
        dims.inequality_rows,
        dims.second_order_cones,
        dims.cone_rows,
        dims.nonzeros,
        dims.hessian_nonzeros
    );
    if let Some((k, l)) = dims.reduced_kkt_nonzeros {
        let _ = writeln!(
            s,
            "interior point: reduced KKT matrix {k} nonzeros (upper triangle), {l} in its LDLᵀ factor"
        );
    }
    out.write_all(s.as_bytes()).map_err(|e| CliError { message: e.to_string(), code: exit::IO })
}

/// The constraints held between the nodes (state bounds and interval constraints), with
/// where their rows sit.
fn between_nodes(s: &mut String, ocp: &armature_scvx::Ocp) {
    use armature_scvx::Sampling;
    let place = |sampling: Sampling| match sampling {
        Sampling::Peak => "at each segment's peak",
        Sampling::GridPoints => "at every integration grid point",
    };
    if ocp.interval_bounds.is_empty() && ocp.interval_constraints.is_empty() {
        return;
    }
    let _ = writeln!(s, "between the nodes:");
    if !ocp.interval_bounds.is_empty() {
        let names: Vec<&str> = ocp
            .interval_bounds
            .iter()
            .map(|&r| ocp.dynamics.state_name(r).unwrap_or("?"))
            .collect();
        let where_ = place(ocp.interval_bounds_sampling);
        let _ = writeln!(s, "  bounds of {}: {where_}", names.join(", "));
    }
    for c in &ocp.interval_constraints {
        let (name, where_) = (&c.name, place(c.sampling));
        let _ = writeln!(s, "  {name:<48} g ≤ 0 {where_}, segments {}..{}", c.first, c.last);
    }
}
