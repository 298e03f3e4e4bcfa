//! Plots of a solution, each as SVG and PNG: joint angles, velocities and torques with their
//! limits; convergence of the SCvx iteration; the end-effector path in top and side views
//! with waypoints, obstacles and the table; the arm drawn as capsules at several instants.
//!
//! PNG text uses the DejaVu Sans font shipped in `assets/` (no system fonts needed). Each
//! file is rendered to a temporary name and renamed, so a failure leaves no partial file.

use std::error::Error;
use std::path::Path;
use std::sync::Once;

use armature_collision::ObstacleShape;
use armature_scvx::Solution;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::pipeline::Plan;
use crate::{CliError, exit};

static FONT: Once = Once::new();

fn register_font() {
    FONT.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../assets/DejaVuSans.ttf");
        // Registration only fails for unparsable bytes; the shipped font parses.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, bytes);
    });
}

/// Stages the plots for `dir` in `set`.
///
/// # Errors
/// Drawing or writing failures ([`exit::IO`]).
pub fn write_plots(
    plan: Option<&Plan>,
    solution: &Solution,
    dir: &Path,
    set: &mut crate::output_set::OutputSet,
) -> Result<(), CliError> {
    register_font();
    // One plot as SVG (rendered in memory, written atomically) and PNG (rendered to a
    // temporary file, renamed).
    macro_rules! plot {
        ($name:expr, $size:expr, $draw:ident, $plan:expr) => {{
            let name: &str = $name;
            let fail = |e: Box<dyn Error>| CliError {
                message: format!("plot {name}: {e}"),
                code: exit::IO,
            };
            let mut text = String::new();
            {
                let root = SVGBackend::with_string(&mut text, $size).into_drawing_area();
                $draw(&root, $plan, solution).map_err(fail)?;
                root.present().map_err(|e| fail(e.into()))?;
            }
            set.stage(&dir.join(format!("{name}.svg")), text.as_bytes())?;
            let tmp = set.stage_path(&dir.join(format!("{name}.png")))?;
            let drawn = (|| -> Result<(), Box<dyn Error>> {
                let root = BitMapBackend::new(&tmp, $size).into_drawing_area();
                $draw(&root, $plan, solution)?;
                root.present()?;
                Ok(())
            })();
            drawn.map_err(fail)?;
        }};
    }
    plot!("convergence", (900, 600), convergence, &());
    match plan {
        Some(plan) => {
            plot!("joints", (1200, 1000), joints, plan);
            plot!("path", (1200, 600), path, plan);
            plot!("arm", (1200, 600), arm, plan);
        }
        None => plot!("trajectory", (1200, 800), series_plot, &()),
    }
    Ok(())
}

/// One colour per joint.
fn color(i: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    C[i % C.len()]
}

fn series<'a>(s: &'a Solution, name: &str) -> (&'a [Vec<f64>], &'a [Vec<f64>]) {
    (s.trajectory["time"].as_slice(), s.trajectory.get(name).map_or(&[][..], Vec::as_slice))
}

fn range(values: impl Iterator<Item = f64>, pad: f64) -> std::ops::Range<f64> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return -1.0..1.0;
    }
    let m = ((hi - lo) * pad).max(1e-6);
    (lo - m)..(hi + m)
}

/// Angles, velocities and torques against time, with dashed limits and node markers.
fn joints<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    plan: &Plan,
    s: &Solution,
) -> Result<(), Box<dyn Error>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let panels = root.split_evenly((3, 1));
    let (qlo, qhi) = plan.chain.position_limits();
    let neg = |v: &[f64]| v.iter().map(|x| -x).collect::<Vec<_>>();
    let specs = [
        ("angle", "joint angle (rad)", qlo, qhi),
        ("velocity", "velocity (rad/s)", neg(&plan.velocity_limit), plan.velocity_limit.clone()),
        ("torque", "torque (N·m)", neg(&plan.torque_limit), plan.torque_limit.clone()),
    ];
    let tf = s.final_time.max(1e-9);
    for (area, (name, label, lo, hi)) in panels.iter().zip(specs) {
        let rows = series(s, name).1;
        let finite_limits = lo.iter().chain(&hi).copied().filter(|v| v.is_finite());
        let y = range(rows.iter().flatten().copied().chain(finite_limits), 0.05);
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{label} — {} in {:.3} s", s.status, s.final_time), ("sans-serif", 18))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..tf, y)?;
        chart.configure_mesh().x_desc("time (s)").y_desc(label).light_line_style(WHITE).draw()?;
        for j in 0..plan.chain.dof() {
            let c = color(j);
            component(&mut chart, s, name, j)?
                .label(format!("joint {}", j + 1))
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], c.stroke_width(2)));
            for bound in [lo[j], hi[j]] {
                if bound.is_finite() {
                    chart.draw_series(DashedLineSeries::new(
                        [(0.0, bound), (tf, bound)],
                        6,
                        4,
                        c.mix(0.5).stroke_width(1),
                    ))?;
                }
            }
        }
        legend(&mut chart)?;
    }
    Ok(())
}

/// Component `j` of series `name` against time in colour `j`: the nodes as dots, the dense
/// trajectory as a line (whose annotation is returned, for a legend entry).
fn component<'b, 'a, DB>(
    chart: &'b mut Chart<'a, DB>,
    s: &Solution,
    name: &str,
    j: usize,
) -> Result<&'b mut plotters::chart::SeriesAnno<'a, DB>, Box<dyn Error>>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
{
    let c = color(j);
    let nodes = s.nodes[name].iter().zip(&s.nodes["time"]);
    chart.draw_series(nodes.map(|(r, t)| Circle::new((t[0], r[j]), 3, c.filled())))?;
    let (t, rows) = series(s, name);
    Ok(chart.draw_series(LineSeries::new(
        t.iter().zip(rows).map(|(t, r)| (t[0], r[j])),
        c.stroke_width(2),
    ))?)
}

/// Every state and control of a problem file against time, one panel each.
fn series_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    _plan: &(),
    s: &Solution,
) -> Result<(), Box<dyn Error>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let names: Vec<&String> = s.trajectory.keys().filter(|k| *k != "time").collect();
    let panels = root.split_evenly((names.len().max(1), 1));
    let tf = s.final_time.max(1e-9);
    for (area, name) in panels.iter().zip(names) {
        let rows = series(s, name).1;
        let y = range(rows.iter().flatten().copied(), 0.05);
        let mut chart = ChartBuilder::on(area)
            .caption(name.as_str(), ("sans-serif", 16))
            .margin(6)
            .x_label_area_size(25)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..tf, y)?;
        chart.configure_mesh().x_desc("time (s)").light_line_style(WHITE).draw()?;
        let width = rows.first().map_or(0, Vec::len);
        for j in 0..width {
            component(&mut chart, s, name, j)?;
        }
    }
    Ok(())
}

/// J_tr, J_vc, J_vb and the largest defect per iteration (log scale), and the cost.
fn convergence<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    _plan: &(),
    s: &Solution,
) -> Result<(), Box<dyn Error>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(400);
    let its = s.history.len().max(1) as f64;
    let floor = 1e-14;
    type Metric = fn(&armature_scvx::Iteration) -> f64;
    let curves: [(&str, Metric, RGBColor); 4] = [
        ("J_tr (step)", |h| h.j_tr, color(0)),
        ("J_vc (virtual control)", |h| h.j_vc, color(1)),
        ("J_vb (virtual buffers)", |h| h.j_vb, color(2)),
        ("largest defect", |h| h.max_defect, color(3)),
    ];
    let all = s.history.iter().flat_map(|h| curves.iter().map(move |c| (c.1)(h)));
    let hi = all.filter(|v| v.is_finite()).fold(floor, f64::max) * 10.0;
    let mut chart = ChartBuilder::on(&top)
        .caption(
            format!("SCvx convergence — {} after {} iterations", s.status, s.iterations),
            ("sans-serif", 18),
        )
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d(0.5..its + 0.5, (floor..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("iteration")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .light_line_style(WHITE)
        .draw()?;
    for (name, f, c) in curves {
        let pts: Vec<(f64, f64)> = s
            .history
            .iter()
            .filter(|h| f(h).is_finite())
            .map(|h| (h.iteration as f64, f(h).max(floor)))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))?
            .label(name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], c.stroke_width(2)));
        chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 2, c.filled())))?;
    }
    legend(&mut chart)?;
    // The iterations that only restored feasibility have no cost (`[time] retime_stall`).
    let minimizing = || s.history.iter().filter(|h| !h.feasibility && h.cost.is_finite());
    let costs = minimizing().map(|h| h.cost);
    let restoring = feasibility_runs(&s.history);
    let cost_desc = if restoring.is_empty() {
        "cost (final time, s; ● accepted, ✕ rejected)".to_string()
    } else {
        format!("cost (final time, s; ● accepted, ✕ rejected; only feasibility at {restoring})")
    };
    let mut chart = ChartBuilder::on(&bottom)
        .margin(8)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d(0.5..its + 0.5, range(costs, 0.1))?;
    chart
        .configure_mesh()
        .x_desc("iteration")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_desc(cost_desc)
        .light_line_style(WHITE)
        .draw()?;
    let pts: Vec<(f64, f64)> = minimizing().map(|h| (h.iteration as f64, h.cost)).collect();
    chart.draw_series(LineSeries::new(pts.clone(), BLACK.stroke_width(2)))?;
    let accepted = minimizing().filter(|h| h.accepted);
    chart.draw_series(
        accepted.map(|h| Circle::new((h.iteration as f64, h.cost), 3, color(2).filled())),
    )?;
    let rejected = minimizing().filter(|h| !h.accepted);
    chart.draw_series(
        rejected.map(|h| Cross::new((h.iteration as f64, h.cost), 4, color(3).stroke_width(2))),
    )?;
    Ok(())
}

/// The iterations that only restored feasibility, as runs: `"19–20, 29"` (a refined solve
/// has one run per stage); empty when there are none.
fn feasibility_runs(history: &[armature_scvx::Iteration]) -> String {
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for h in history.iter().filter(|h| h.feasibility) {
        match runs.last_mut() {
            Some((_, last)) if *last + 1 == h.iteration => *last = h.iteration,
            _ => runs.push((h.iteration, h.iteration)),
        }
    }
    let run = |&(a, b): &(usize, usize)| if a == b { a.to_string() } else { format!("{a}–{b}") };
    runs.iter().map(run).collect::<Vec<_>>().join(", ")
}

/// Projection axes of the two views: top (x, y) and side (x, z).
const VIEWS: [(&str, usize, usize); 2] = [("top view", 0, 1), ("side view", 0, 2)];

/// Outline of a capsule (segment a–b, radius r) projected on axes (i, j).
fn stadium(a: [f64; 3], b: [f64; 3], r: f64, (i, j): (usize, usize)) -> Vec<(f64, f64)> {
    let (ax, ay, bx, by) = (a[i], a[j], b[i], b[j]);
    let ang = (by - ay).atan2(bx - ax);
    let mut pts = Vec::new();
    for k in 0..=16 {
        let t = ang + std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * k as f64 / 16.0;
        pts.push((ax + r * t.cos(), ay + r * t.sin()));
    }
    for k in 0..=16 {
        let t = ang - std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * k as f64 / 16.0;
        pts.push((bx + r * t.cos(), by + r * t.sin()));
    }
    pts.push(pts[0]);
    pts
}

/// Equal-scale ranges around `points` for a panel of `w × h` pixels.
fn square(points: &[(f64, f64)], w: f64, h: f64) -> (std::ops::Range<f64>, std::ops::Range<f64>) {
    let x = range(points.iter().map(|p| p.0), 0.08);
    let y = range(points.iter().map(|p| p.1), 0.08);
    let scale = ((x.end - x.start) / w).max((y.end - y.start) / h);
    let (cx, cy) = ((x.start + x.end) / 2.0, (y.start + y.end) / 2.0);
    ((cx - scale * w / 2.0)..(cx + scale * w / 2.0), (cy - scale * h / 2.0)..(cy + scale * h / 2.0))
}

/// Obstacles, table and waypoints in one view.
fn scenery<DB: DrawingBackend>(
    chart: &mut ChartContext<
        '_,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    plan: &Plan,
    (i, j): (usize, usize),
    x: &std::ops::Range<f64>,
) -> Result<(), Box<dyn Error>>
where
    DB::ErrorType: 'static,
{
    let grey = RGBColor(120, 120, 120);
    if let (Some(h), 2) = (plan.table_height, j) {
        chart.draw_series(std::iter::once(PathElement::new(
            [(x.start, h), (x.end, h)],
            grey.stroke_width(3),
        )))?;
    }
    if let Some(model) = &plan.collision {
        for o in model.obstacles() {
            let outline = match &o.shape {
                ObstacleShape::Sphere { center, radius } => {
                    Some(stadium((*center).into(), (*center).into(), *radius, (i, j)))
                }
                ObstacleShape::Capsule { a, b, radius } => {
                    Some(stadium((*a).into(), (*b).into(), *radius, (i, j)))
                }
                _ => None,
            };
            if let Some(pts) = outline {
                chart.draw_series(std::iter::once(Polygon::new(
                    pts,
                    RGBColor(214, 39, 40).mix(0.3),
                )))?;
            }
        }
    }
    // Waypoints that coincide in this view (e.g. grasp under pre_grasp, seen from above)
    // share one label instead of printing over each other.
    let mut labels: Vec<((f64, f64), String)> = Vec::new();
    for w in &plan.waypoints {
        let p = w.position;
        chart.draw_series(std::iter::once(PathElement::new(
            stadium(p, p, w.tolerance, (i, j)),
            BLACK.stroke_width(1),
        )))?;
        let at = (p[i], p[j]);
        match labels.iter_mut().find(|(q, _)| (q.0 - at.0).hypot(q.1 - at.1) < 1e-3) {
            Some((_, text)) if text.split(", ").any(|n| n == w.name) => {}
            Some((_, text)) => {
                text.push_str(", ");
                text.push_str(&w.name);
            }
            None => labels.push((at, w.name.clone())),
        }
    }
    for (at, text) in labels {
        // Beside the marker rather than on it.
        chart.draw_series(std::iter::once(
            EmptyElement::at(at) + Text::new(text, (8, -6), ("sans-serif", 12)),
        ))?;
    }
    Ok(())
}

type Chart<'a, DB> = ChartContext<
    'a,
    DB,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// An equal-scale chart of one view (axes `i`, `j`) around `pts`, with the scenery drawn.
fn view<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    caption: String,
    pts: &[(f64, f64)],
    plan: &Plan,
    (i, j): (usize, usize),
) -> Result<Chart<'a, DB>, Box<dyn Error>>
where
    DB::ErrorType: 'static,
{
    let (w, h) = area.dim_in_pixel();
    let (x, y) = square(pts, f64::from(w) - 80.0, f64::from(h) - 80.0);
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(x.clone(), y)?;
    let axis = ["x (m)", "y (m)", "z (m)"];
    chart.configure_mesh().x_desc(axis[i]).y_desc(axis[j]).light_line_style(WHITE).draw()?;
    scenery(&mut chart, plan, (i, j), &x)?;
    Ok(chart)
}

/// The series legend in the upper right corner.
fn legend<'a, DB, CT>(chart: &mut ChartContext<'a, DB, CT>) -> Result<(), Box<dyn Error>>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    CT: plotters::coord::CoordTranslate,
{
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK.mix(0.3))
        .label_font(("sans-serif", 12))
        .draw()?;
    Ok(())
}

/// The end-effector path (dense, nodes marked) in top and side views.
fn path<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    plan: &Plan,
    s: &Solution,
) -> Result<(), Box<dyn Error>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    for (area, (title, i, j)) in root.split_evenly((1, 2)).iter().zip(VIEWS) {
        let ee = &s.trajectory["ee_position"];
        let mut pts: Vec<(f64, f64)> = ee.iter().map(|p| (p[i], p[j])).collect();
        pts.extend(plan.waypoints.iter().map(|w| (w.position[i], w.position[j])));
        let mut chart = view(area, format!("end-effector path, {title}"), &pts, plan, (i, j))?;
        chart.draw_series(LineSeries::new(
            ee.iter().map(|p| (p[i], p[j])),
            color(0).stroke_width(2),
        ))?;
        let nodes = s.nodes["ee_position"].iter();
        chart.draw_series(nodes.map(|p| Circle::new((p[i], p[j]), 3, color(0).filled())))?;
    }
    Ok(())
}

/// The arm as capsules (or segments without a collision model) at several instants.
fn arm<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    plan: &Plan,
    s: &Solution,
) -> Result<(), Box<dyn Error>>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let chain = &plan.chain;
    let mut fk = chain.fk_workspace();
    let angles = &s.trajectory["angle"];
    let count = 7.min(angles.len());
    let picks: Vec<usize> =
        (0..count).map(|k| k * (angles.len() - 1) / (count - 1).max(1)).collect();
    let mut frames: Vec<Vec<[f64; 3]>> = Vec::new();
    for &k in &picks {
        chain.forward(&angles[k], &mut fk)?;
        frames.push((0..chain.keypoints().len()).map(|i| fk.keypoint_position(i).into()).collect());
    }
    let links: Vec<(usize, usize, f64)> = match &plan.collision {
        Some(m) => m.links().iter().map(|l| (l.start, l.end, l.radius)).collect(),
        None => (1..chain.keypoints().len()).map(|i| (i - 1, i, 0.01)).collect(),
    };
    let times = &s.trajectory["time"];
    for (area, (title, i, j)) in root.split_evenly((1, 2)).iter().zip(VIEWS) {
        let pts: Vec<(f64, f64)> = frames.iter().flatten().map(|p| (p[i], p[j])).collect();
        let caption = format!("the arm at {count} instants, {title}");
        let mut chart = view(area, caption, &pts, plan, (i, j))?;
        for (n, (kp, &k)) in frames.iter().zip(&picks).enumerate() {
            let c = color(n);
            for &(a, b, r) in &links {
                chart.draw_series(std::iter::once(PathElement::new(
                    stadium(kp[a], kp[b], r, (i, j)),
                    c.stroke_width(2),
                )))?;
            }
            let last = kp[kp.len() - 1];
            chart
                .draw_series(std::iter::once(Circle::new((last[i], last[j]), 3, c.filled())))?
                .label(format!("t = {:.2} s", times[k][0]))
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], c.stroke_width(2)));
        }
        legend(&mut chart)?;
    }
    Ok(())
}
