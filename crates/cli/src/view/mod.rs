//! `--html` and `armature view`: one self-contained HTML file that shows a result in 3D —
//! the arm moving along the dense trajectory, the obstacles, the table, the waypoints with
//! their tolerances — with playback controls and a readout of the clearance and of every
//! joint against its limits.
//!
//! The page is three.js (vendored once from the npm registry, see `assets/three/`), the
//! viewer script `assets/view.js` and the result's data, all embedded in the file: it opens
//! from disk with no network and no server.

mod data;
mod scene;

pub use data::{Iterate, RetimedView, ViewData};
pub use scene::{
    JointLimits, Scene, SceneClearance, SceneKeypoint, SceneLink, SceneObstacle, SceneOrientation,
    SceneShape, SceneWaypoint, THIN_LINK_RADIUS,
};

const TEMPLATE: &str = include_str!("../../assets/view.html");
const THREE: &str = include_str!("../../assets/three/three-bundle.min.js");
const THREE_LICENSE: &str = include_str!("../../assets/three/LICENSE");
const VIEWER: &str = include_str!("../../assets/view.js");

/// The page for `data`, as one HTML document.
///
/// # Errors
/// A serialization failure (it does not happen for data that passed [`ViewData::check`]).
pub fn html(data: &ViewData) -> Result<String, serde_json::Error> {
    // `<` only occurs inside JSON strings, where `\u003c` means the same: no name can end
    // the script element early.
    let json = serde_json::to_string(data)?.replace('<', "\\u003c");
    let title = format!("armature · {}", data.source).replace('&', "&amp;").replace('<', "&lt;");
    Ok(TEMPLATE
        .replacen("{{TITLE}}", &title, 1)
        .replacen("{{THREE_LICENSE}}", &THREE_LICENSE.replace("*/", "* /"), 1)
        .replacen("{{THREE}}", &THREE.replace("</script", "<\\/script"), 1)
        .replacen("{{VIEWER}}", VIEWER, 1)
        .replacen("{{DATA}}", &json, 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(source: &str) -> ViewData {
        let trajectory = [("time".to_string(), vec![vec![0.0], vec![1.0]])].into_iter().collect();
        ViewData {
            source: source.into(),
            status: "converged".into(),
            final_time: 1.0,
            iterations: 3,
            max_violation: None,
            trajectory,
            scene: None,
            iterates: Vec::new(),
            retimed: None,
        }
    }

    #[test]
    fn every_placeholder_is_filled_once_and_names_cannot_close_the_script() {
        let page = html(&data("</script><script>alert(1)</script> & co")).unwrap();
        for marker in ["{{TITLE}}", "{{THREE_LICENSE}}", "{{THREE}}", "{{VIEWER}}", "{{DATA}}"] {
            assert!(!page.contains(marker), "{marker}");
        }
        // The template's four scripts (error capture, three.js, the data, the viewer), no more.
        assert_eq!(page.matches("</script>").count(), 4);
        assert!(page.contains(
            "<title>armature · &lt;/script>&lt;script>alert(1)&lt;/script> &amp; co</title>"
        ));
        let start = page.find("id=\"armature-data\">").unwrap() + "id=\"armature-data\">".len();
        let json = &page[start..start + page[start..].find("</script>").unwrap()];
        let back: ViewData = serde_json::from_str(json).unwrap();
        assert_eq!(back, data("</script><script>alert(1)</script> & co"));
        assert!(page.contains("Copyright © 2010-2026 three.js authors"));
    }
}
