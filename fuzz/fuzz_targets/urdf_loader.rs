//! The URDF loader on arbitrary bytes: the first line names the base link, the second the
//! tip, the rest is the URDF.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let mut parts = text.splitn(3, '\n');
    let (Some(base), Some(tip), Some(xml)) = (parts.next(), parts.next(), parts.next()) else {
        return;
    };
    if let Ok(chain) = armature_kinematics::chain_from_urdf_str(xml, base, tip, None) {
        // A chain that loads evaluates: its forward kinematics at zero is finite.
        let mut ws = chain.fk_workspace();
        if chain.forward(&vec![0.0; chain.dof()], &mut ws).is_ok() {
            assert!(ws.ee().translation().iter().all(|v| v.is_finite()));
        }
    }
});
