//! End-to-end: `--html` and `armature view` write one self-contained page; opened in headless
//! Chromium (Debian's `chromium`, which `.ci/run` installs) it renders without console
//! errors, the canvas is not blank, the arm's pixels move as the slider moves, and the
//! clearance readout at the closest instant is the result's own value. Bad input to `view`
//! gives its message, exit code 2 and no page.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{armature, scratch};
use serde_json::Value;

const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures");
/// The window the screenshots are taken in; the panel covers x < 380 px.
const WIDTH: usize = 1000;
const HEIGHT: usize = 700;
const SCENE_X0: usize = 380;
/// The page's clear colour (#f4f5f7).
const BACKGROUND: [u8; 3] = [0xf4, 0xf5, 0xf7];

fn chromium() -> PathBuf {
    let path = std::env::var_os("PATH").unwrap_or_default();
    for dir in std::env::split_paths(&path) {
        for name in ["chromium", "chromium-browser", "google-chrome"] {
            let candidate = dir.join(name);
            if candidate.is_file() {
                return candidate;
            }
        }
    }
    panic!("the 3D view's test needs headless Chromium: `apt-get install chromium` (.ci/run does)");
}

/// An RGB screenshot.
struct Shot {
    rgb: Vec<[u8; 3]>,
}

impl Shot {
    fn read(path: &Path) -> Shot {
        let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width as usize, info.height as usize), (WIDTH, HEIGHT));
        let bpp = info.line_size / WIDTH;
        assert!(bpp >= 3 && info.bit_depth == png::BitDepth::Eight, "{info:?}");
        let rgb = buf[..info.buffer_size()].chunks(bpp).map(|p| [p[0], p[1], p[2]]).collect();
        Shot { rgb }
    }

    /// The pixels right of the panel.
    fn scene(&self) -> impl Iterator<Item = [u8; 3]> + '_ {
        (0..HEIGHT).flat_map(move |y| (SCENE_X0..WIDTH).map(move |x| self.rgb[y * WIDTH + x]))
    }

    /// Fraction of the scene's pixels that differ by more than 40 in some channel from `other`.
    fn differs(&self, other: &Shot) -> f64 {
        let n = self.scene().zip(other.scene()).filter(|(a, b)| far(*a, *b)).count();
        n as f64 / ((WIDTH - SCENE_X0) * HEIGHT) as f64
    }

    /// Fraction of the scene's pixels that are not the background.
    fn drawn(&self) -> f64 {
        let n = self.scene().filter(|p| far(*p, BACKGROUND)).count();
        n as f64 / ((WIDTH - SCENE_X0) * HEIGHT) as f64
    }
}

fn far(a: [u8; 3], b: [u8; 3]) -> bool {
    a.iter().zip(&b).any(|(x, y)| x.abs_diff(*y) > 40)
}

/// The page opened at `#t=…` (or another hash): the DOM after the first frames and a screenshot.
struct Opened {
    dom: String,
    shot: Shot,
}

fn run_chromium(profile: &Path, args: &[&str]) -> std::process::Output {
    let out = Command::new(chromium())
        .args(["--headless", "--no-sandbox", "--hide-scrollbars", "--mute-audio"])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--window-size={WIDTH},{HEIGHT}"))
        .arg("--virtual-time-budget=5000")
        .args(args)
        .output()
        .expect("chromium runs");
    assert!(out.status.success(), "chromium: {}", String::from_utf8_lossy(&out.stderr));
    out
}

fn open(page: &Path, hash: &str) -> Opened {
    let url = format!("file://{}#{hash}", page.display());
    let dir = page.parent().unwrap();
    let tag = hash.replace(['=', '.', '&'], "_");
    let png = dir.join(format!("shot-{tag}.png"));
    run_chromium(
        &dir.join(format!("profile-shot-{tag}")),
        &[&format!("--screenshot={}", png.display()), &url],
    );
    let out = run_chromium(&dir.join(format!("profile-dom-{tag}")), &["--dump-dom", &url]);
    let dom = String::from_utf8(out.stdout).unwrap();
    let opened = Opened { dom, shot: Shot::read(&png) };
    opened.assert_healthy(hash);
    opened
}

impl Opened {
    /// The attribute `attr` of the element with id `id` as the page rendered it (the viewer
    /// script's own source, which the DOM also holds, has `${…}` there).
    fn attribute(&self, id: &str, attr: &str) -> Option<String> {
        let start = format!("id=\"{id}\"");
        self.dom.match_indices(&start).find_map(|(i, _)| {
            let tag = &self.dom[i..i + self.dom[i..].find('>')?];
            let key = format!("{attr}=\"");
            let v = &tag[tag.find(&key)? + key.len()..];
            let v = &v[..v.find('"')?];
            (!v.starts_with("${")).then(|| v.to_string())
        })
    }

    fn number(&self, id: &str, attr: &str) -> f64 {
        let v = self.attribute(id, attr).unwrap_or_else(|| panic!("no {id} {attr} in the page"));
        v.parse().unwrap_or_else(|_| panic!("{id} {attr} = {v}"))
    }

    /// No console errors, at least one frame drawn, a canvas that is not blank.
    fn assert_healthy(&self, hash: &str) {
        assert!(
            self.dom.contains("<pre id=\"errors\" hidden=\"\"></pre>"),
            "#{hash}: the page reported errors: {}",
            &self.dom[self.dom.find("id=\"errors\"").unwrap_or(0)..][..300.min(self.dom.len())]
        );
        let frames =
            self.dom.split("<body data-frames=\"").nth(1).and_then(|s| s.split('"').next());
        let frames: usize = frames.and_then(|f| f.parse().ok()).unwrap_or(0);
        assert!(frames >= 1, "#{hash}: no frame was drawn");
        assert!(self.shot.drawn() > 0.01, "#{hash}: the canvas is blank ({})", self.shot.drawn());
    }
}

/// A solve that ran to its end and wrote its outputs: converged (0), or stopped otherwise
/// (3, e.g. converged at the nodes with a violation between them) — the view shows both.
fn solved(code: i32, stderr: &str) {
    assert!(code == 0 || code == 3, "exit {code}: {stderr}");
}

fn read_json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The dense instant of the smallest clearance over all pairs: (time, value, pair name).
fn closest(result: &Value) -> (f64, f64, String) {
    // The view plays the retimed trajectory when the result has one.
    let shown = result.get("retimed").unwrap_or(result);
    let times = shown["trajectory"]["time"].as_array().unwrap();
    let rows = shown["trajectory"]["clearance"].as_array().unwrap();
    let pairs = result["scene"]["clearance"]["pairs"].as_array().unwrap();
    let mut best = (f64::INFINITY, 0, 0);
    for (k, row) in rows.iter().enumerate() {
        for (p, v) in row.as_array().unwrap().iter().enumerate() {
            let v = v.as_f64().unwrap();
            if v < best.0 {
                best = (v, k, p);
            }
        }
    }
    (times[best.1][0].as_f64().unwrap(), best.0, pairs[best.2].as_str().unwrap().to_string())
}

fn assert_self_contained(page: &Path) {
    let html = std::fs::read_to_string(page).unwrap();
    assert!(html.len() < 3_000_000, "{} bytes", html.len());
    for tag in ["<script src", "<link ", "<img ", "@import"] {
        assert!(!html.contains(tag), "the page loads something: {tag}");
    }
}

#[test]
fn the_collision_demo_plays_in_a_browser_and_its_readout_is_the_results() {
    let dir = scratch("view-demo");
    let (json, page) = (dir.path().join("r.json"), dir.path().join("view.html"));
    let (code, _, stderr) = armature(&[
        "demo",
        "pick-and-place-collision",
        "-q",
        "-o",
        json.to_str().unwrap(),
        "--html",
        page.to_str().unwrap(),
    ]);
    solved(code, &stderr);
    assert_self_contained(&page);
    let result = read_json(&json);
    let tf = result.get("retimed").unwrap_or(&result)["final_time"].as_f64().unwrap();
    let (t_closest, value, pair) = closest(&result);
    let times = [0.1 * tf, 0.45 * tf, t_closest];
    let opened: Vec<Opened> = times.iter().map(|t| open(&page, &format!("t={t}"))).collect();
    for (o, t) in opened.iter().zip(times) {
        // A range input keeps 15 significant digits of its value.
        let shown = o.number("time", "data-value");
        assert!((shown - t).abs() <= 1e-12 * t.max(1.0), "the slider moved to {t}, not {shown}");
    }
    for (i, j) in [(0, 1), (1, 2), (0, 2)] {
        let moved = opened[i].shot.differs(&opened[j].shot);
        assert!(moved > 0.002, "t = {} → {}: {moved} of the pixels changed", times[i], times[j]);
    }
    let at = &opened[2];
    let shown = at.number("clearance", "data-value");
    assert!((shown - value).abs() <= 1e-6, "readout {shown} vs the result's {value}");
    assert_eq!(at.attribute("clearance", "data-pair").as_deref(), Some(pair.as_str()));
    // `#t=closest` finds the same instant by itself.
    let found = open(&page, "t=closest");
    assert!((found.number("time", "data-value") - t_closest).abs() <= 1e-12);
    // `armature view` on the result file writes the same view.
    let again = dir.path().join("again.html");
    let (code, _, stderr) =
        armature(&["view", json.to_str().unwrap(), "-o", again.to_str().unwrap(), "-q"]);
    assert_eq!(code, 0, "{stderr}");
    let reopened = open(&again, &format!("t={t_closest}"));
    assert_eq!(reopened.number("clearance", "data-value"), shown);
}

#[test]
fn a_urdf_arm_and_a_problem_file_with_a_frame_render_and_move() {
    let dir = scratch("view-urdf");
    for (task, hashes) in
        [("ur5e-like-pick.toml", ["t=0.2", "t=0.7"]), ("frames-problem.toml", ["t=0.3", "t=2"])]
    {
        let page = dir.path().join(format!("{task}.html"));
        let file = Path::new(FIXTURES).join(task);
        let (code, _, stderr) =
            armature(&["solve", file.to_str().unwrap(), "-q", "--html", page.to_str().unwrap()]);
        solved(code, &stderr);
        assert_self_contained(&page);
        let [a, b] = hashes.map(|h| open(&page, h));
        assert!(a.shot.differs(&b.shot) > 0.001, "{task}: nothing moved");
        assert!(a.attribute("message", "hidden").is_some(), "{task}: the page shows a message");
        if task.ends_with("pick.toml") {
            // The toggle draws the guess and the iterates (the result holds them).
            let with = open(&page, &format!("{}&iterates", hashes[0]));
            assert!(with.shot.differs(&a.shot) > 0.0005, "the iterates are not drawn");
        }
    }
}

#[test]
fn a_result_without_geometry_or_frames_says_so_in_the_page() {
    let dir = scratch("view-none");
    let page = dir.path().join("view.html");
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/double-integrator.toml");
    let (code, _, stderr) = armature(&["solve", file, "-q", "--html", page.to_str().unwrap()]);
    solved(code, &stderr);
    let url = format!("file://{}", page.display());
    let out = run_chromium(&dir.path().join("profile"), &["--dump-dom", &url]);
    let dom = String::from_utf8(out.stdout).unwrap();
    assert!(dom.contains("<div id=\"message\"><b>Nothing to draw.</b>"), "{dom}");
    assert!(dom.contains("<pre id=\"errors\" hidden=\"\"></pre>"));
}

#[test]
fn view_rejects_what_is_not_a_result_and_writes_nothing() {
    let dir = scratch("view-bad");
    let page = dir.path().join("view.html");
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let good = dir.path().join("good.json");
    let (code, _, stderr) = armature(&["demo", "-q", "-o", good.to_str().unwrap()]);
    solved(code, &stderr);
    let mut bad_link = read_json(&good);
    bad_link["scene"]["links"][0]["end"] = 99.into();
    let mut no_frame = read_json(&good);
    no_frame["retimed"]["trajectory"].as_object_mut().unwrap().remove("T_elbow");
    let cases = [
        (dir.path().join("missing.json").to_str().unwrap().to_string(), "No such file"),
        (write("syntax.json", "{\n  \"status\": \"converged\",\n  oops\n}"), "syntax.json:3:3:"),
        (write("array.json", "\n  [1, 2]"), "array.json:2:3: a result file is a JSON object"),
        (
            write(
                "no-time.json",
                r#"{"status":"converged","final_time":1,"iterations":1,"trajectory":{}}"#,
            ),
            "no `time` series",
        ),
        (
            write("link.json", &bad_link.to_string()),
            "link `base-shoulder` joins keypoints 0 and 99; there are 5",
        ),
        (
            write("frame.json", &no_frame.to_string()),
            "keypoint `elbow` needs a 4×4 frame series `T_elbow`",
        ),
    ];
    for (input, expected) in cases {
        let (code, _, stderr) = armature(&["view", &input, "-o", page.to_str().unwrap()]);
        assert_eq!(code, 2, "{input}: {stderr}");
        assert!(stderr.contains(expected), "{input}: {stderr}");
        assert!(!page.exists(), "{input}: a page was written");
    }
    // A problem file gives no geometry to `--task`.
    let problem = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/double-integrator.toml");
    let (code, _, stderr) = armature(&[
        "view",
        good.to_str().unwrap(),
        "--task",
        problem,
        "-o",
        page.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("a problem file has no robot geometry"), "{stderr}");
    assert!(!page.exists());
    // The seed's own task file gives the same geometry the result holds.
    let task = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/pick-and-place.toml");
    let (code, _, stderr) =
        armature(&["view", good.to_str().unwrap(), "--task", task, "-o", page.to_str().unwrap()]);
    assert_eq!(code, 0, "{stderr}");
    assert!(page.exists());
}
