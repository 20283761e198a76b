//! The measured acceleration `q̈`: finite differences of the measured velocities `q̇` over the
//! samples' time base (header stamps or log times), within segments.
//!
//! Samples `i − 1` and `i` are one segment when both carry velocities and
//! `0 < t_i − t_{i−1} ≤ max_gap`: no difference is taken across a gap, a step back in time or
//! a message without velocities.

/// Whether a sample at `t` (ns) continues the segment of the sample before it, `prev` =
/// `(t_prev, prev has velocities)`.
pub fn joins(prev: Option<(i64, bool)>, t: i64, has_velocity: bool, max_gap_ns: i64) -> bool {
    match prev {
        Some((t_prev, prev_velocity)) => {
            prev_velocity && has_velocity && t > t_prev && t - t_prev <= max_gap_ns
        }
        None => false,
    }
}

/// `q̈_i`, the derivative at `t_i` of the measured velocities, from the neighbours that share a
/// segment with sample `i` (`h_prev = t_i − t_{i−1} > 0`, `h_next = t_{i+1} − t_i > 0`, seconds):
///
/// ```text
/// both:        q̈_i = [h₋² (q̇_{i+1} − q̇_i) + h₊² (q̇_i − q̇_{i−1})] / (h₋ h₊ (h₋ + h₊))
///              (the slope at t_i of the parabola through the three samples; second order,
///               (q̇_{i+1} − q̇_{i−1}) / 2h for equal steps)
/// next only:   q̈_i = (q̇_{i+1} − q̇_i) / h₊      (first sample of a segment; first order)
/// prev only:   q̈_i = (q̇_i − q̇_{i−1}) / h₋      (last sample of a segment; first order)
/// ```
///
/// Returns `false` (and leaves `out` alone) for a sample with neither neighbour.
pub fn velocity_derivative(
    prev: Option<(f64, &[f64])>,
    v: &[f64],
    next: Option<(f64, &[f64])>,
    out: &mut [f64],
) -> bool {
    match (prev, next) {
        (Some((hm, vm)), Some((hp, vp))) => {
            let (wm, wp) = (hp * hp, hm * hm);
            let d = hm * hp * (hm + hp);
            for k in 0..v.len() {
                out[k] = (wp * (vp[k] - v[k]) + wm * (v[k] - vm[k])) / d;
            }
        }
        (None, Some((hp, vp))) => {
            for k in 0..v.len() {
                out[k] = (vp[k] - v[k]) / hp;
            }
        }
        (Some((hm, vm)), None) => {
            for k in 0..v.len() {
                out[k] = (v[k] - vm[k]) / hm;
            }
        }
        (None, None) => return false,
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The three-point formula is exact for a quadratic velocity on uneven steps; the one-sided
    /// ones for a linear one.
    #[test]
    fn differences_are_exact_for_polynomials_of_their_order() {
        let v = |t: f64| [3.0 * t * t - 2.0 * t + 1.0, -t * t];
        let dv = |t: f64| [6.0 * t - 2.0, -2.0 * t];
        let (t0, t1, t2) = (0.3, 0.31, 0.337);
        let mut out = [0.0; 2];
        assert!(velocity_derivative(
            Some((t1 - t0, &v(t0))),
            &v(t1),
            Some((t2 - t1, &v(t2))),
            &mut out
        ));
        for k in 0..2 {
            assert!((out[k] - dv(t1)[k]).abs() < 1e-9, "{out:?} vs {:?}", dv(t1));
        }
        let line = |t: f64| [2.0 * t + 1.0, -5.0 * t];
        assert!(velocity_derivative(
            None,
            &line(t0),
            Some((t1 - t0, &line(t1))),
            &mut out
        ));
        assert!((out[0] - 2.0).abs() < 1e-9 && (out[1] + 5.0).abs() < 1e-9);
        assert!(velocity_derivative(
            Some((t2 - t1, &line(t1))),
            &line(t2),
            None,
            &mut out
        ));
        assert!((out[0] - 2.0).abs() < 1e-9 && (out[1] + 5.0).abs() < 1e-9);
        assert!(!velocity_derivative(None, &line(t0), None, &mut out));
    }

    #[test]
    fn segments_break_at_gaps_steps_back_and_missing_velocities() {
        let gap = 100;
        assert!(joins(Some((0, true)), 100, true, gap));
        assert!(!joins(Some((0, true)), 101, true, gap));
        assert!(!joins(Some((50, true)), 50, true, gap));
        assert!(!joins(Some((50, true)), 40, true, gap));
        assert!(!joins(Some((0, false)), 10, true, gap));
        assert!(!joins(Some((0, true)), 10, false, gap));
        assert!(!joins(None, 10, true, gap));
    }
}
