//! How the controls are held between the nodes, and the physical control profile of a
//! nodal trajectory: first- or zero-order hold, and time scaling (the solver's variable is
//! `w = s·u` for a time-scaled entry, see [`Dynamics::time_scaled`]).
//!
//! # Math
//! On segment k (dilation `s_k`) a first-order-hold entry runs linearly from its value at
//! the segment's start to its value at its end; a zero-order-hold one keeps its start value.
//! A time-scaled entry is `u(τ) = w(τ)/s_k`: from `w_k/s_k` to `w_{k+1}/s_k`, so where two
//! segments' dilations differ, the physical control jumps at the node between them (from
//! `w_{k+1}/s_k` to `w_{k+1}/s_{k+1}`).

use super::Dynamics;

/// The hold of every control entry: first-order (else zero-order) and time-scaled.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ControlHolds {
    /// First-order hold, per control entry.
    pub foh: Vec<bool>,
    /// Time-scaled, per control entry.
    pub time_scaled: Vec<bool>,
}

/// A nodal trajectory's physical controls on each segment: its value where each segment
/// starts (`N` rows of m, the last node the end of the last segment) and where it ends
/// (`N − 1` rows).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ControlProfile {
    /// The value at the start of segment k (row k, N×m row-major); row N − 1 is the end of
    /// the last segment.
    pub starts: Vec<f64>,
    /// The value at the end of segment k (row k, (N − 1)×m row-major).
    pub ends: Vec<f64>,
}

impl ControlHolds {
    /// Whether any entry is time-scaled.
    pub fn any_time_scaled(&self) -> bool {
        self.time_scaled.iter().any(|&t| t)
    }

    /// The solver's variables from physical nodal controls `u` (N×m) with the dilations
    /// `s` (N): `w = s·u` on time-scaled entries, with the dilation of the segment the node
    /// starts (the last node: of the segment it ends); the others unchanged.
    pub fn to_solver(&self, u: &mut [f64], s: &[f64]) {
        let (m, nn) = (self.foh.len(), s.len());
        if m == 0 || nn < 2 || !self.any_time_scaled() {
            return;
        }
        for (k, row) in u.chunks_mut(m).enumerate().take(nn) {
            let sk = s[k.min(nn - 2)];
            for (v, _) in row.iter_mut().zip(&self.time_scaled).filter(|(_, t)| **t) {
                *v *= sk;
            }
        }
    }

    /// The physical control profile of the solver's nodal variables `u` (N×m) with the
    /// dilations `s` (N). See the module's math.
    pub fn profile(&self, u: &[f64], s: &[f64]) -> ControlProfile {
        let (m, nn) = (self.foh.len(), s.len());
        let mut p = ControlProfile { starts: u.to_vec(), ends: Vec::new() };
        if nn < 2 || m == 0 {
            return p;
        }
        p.ends = vec![0.0; (nn - 1) * m];
        for k in 0..nn - 1 {
            for i in 0..m {
                let (start, end) = (u[k * m + i], u[(k + 1) * m + i]);
                let scale = if self.time_scaled[i] { 1.0 / s[k] } else { 1.0 };
                p.starts[k * m + i] = start * scale;
                p.ends[k * m + i] = if self.foh[i] { end } else { start } * scale;
            }
        }
        for i in 0..m {
            // The last node: where the last segment ends (its own value for a plain entry).
            if self.time_scaled[i] {
                p.starts[(nn - 1) * m + i] = u[(nn - 1) * m + i] / s[nn - 2];
            }
        }
        p
    }
}

impl Dynamics {
    /// The holds of the controls (first-order, time-scaled).
    pub fn holds(&self) -> ControlHolds {
        ControlHolds { foh: self.foh.clone(), time_scaled: self.time_scaled.clone() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_time_scaled_control_jumps_where_the_dilation_changes() {
        // Entry 0 first-order and time-scaled, entry 1 first-order, entry 2 zero-order.
        let holds =
            ControlHolds { foh: vec![true, true, false], time_scaled: vec![true, false, false] };
        let s = [2.0, 4.0, 4.0];
        let physical = [1.0, 5.0, 7.0, 2.0, 6.0, 8.0, 3.0, 7.0, 9.0];
        let mut w = physical;
        holds.to_solver(&mut w, &s);
        assert_eq!(w, [2.0, 5.0, 7.0, 8.0, 6.0, 8.0, 12.0, 7.0, 9.0]);
        let p = holds.profile(&w, &s);
        // Starts: the physical values back; the last node is the end of the last segment.
        assert_eq!(p.starts, physical);
        // Segment 0 ends at w_1/s_0 = 8/2 = 4 (not 2: the dilation changes at node 1).
        assert_eq!(p.ends, [4.0, 6.0, 7.0, 3.0, 7.0, 8.0]);
    }

    #[test]
    fn without_time_scaling_the_profile_is_the_nodes() {
        let holds = ControlHolds { foh: vec![true], time_scaled: vec![false] };
        let (u, s) = ([1.0, 2.0, 3.0], [1.0, 2.0, 2.0]);
        let mut w = u;
        holds.to_solver(&mut w, &s);
        assert_eq!(w, u);
        let p = holds.profile(&u, &s);
        assert_eq!((p.starts.as_slice(), p.ends.as_slice()), (&u[..], &[2.0, 3.0][..]));
    }
}
