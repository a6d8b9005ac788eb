//! BART keyframe animation: Kochanek–Bartels splines for translation and
//! scale, squad with TCB tangents for rotation.
//!
//! Kochanek & Bartels, "Interpolating Splines with Local Tension,
//! Continuity, and Bias Control", SIGGRAPH 1984; Shoemake, "Animating
//! Rotation with Quaternion Curves", SIGGRAPH 1985; and the BART reference
//! code (Lext, Assarsson, Möller 2001):
//! - the first and last keys only shape tangents; time is clamped to the
//!   range from the second to the second-to-last key;
//! - tangents are scaled by `2 (t[i+1] - t[i]) / (t[i+1] - t[i-1])` (and the
//!   mirror factor at the segment's end) for non-uniform key spacing;
//! - rotation keys are absolute axis-angle rotations (axes normalised, angles
//!   in degrees, possibly far beyond 360); each quaternion's sign is flipped
//!   where needed so that neighbours are less than 90 degrees apart in
//!   quaternion space (the short way).

use glam::{Mat4, Quat, Vec3};

/// Tension, continuity and bias of a key.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tcb {
    /// Tension.
    pub tension: f32,
    /// Continuity.
    pub continuity: f32,
    /// Bias.
    pub bias: f32,
}

/// A translation or scale key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VecKey {
    /// Time.
    pub time: f32,
    /// Value.
    pub value: Vec3,
    /// Spline parameters.
    pub tcb: Tcb,
}

/// A rotation key: absolute rotation of `degrees` about `axis`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotKey {
    /// Time.
    pub time: f32,
    /// Rotation axis (any non-zero length).
    pub axis: Vec3,
    /// Angle in degrees.
    pub degrees: f32,
    /// Spline parameters.
    pub tcb: Tcb,
}

/// The keyframes of one animated node (`k name { ... }`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Track {
    /// Translation keys.
    pub translation: Vec<VecKey>,
    /// Rotation keys.
    pub rotation: Vec<RotKey>,
    /// Scale keys.
    pub scale: Vec<VecKey>,
}

/// Source (outgoing) and destination (incoming) TCB weights for the
/// differences `(p[i] - p[i-1], p[i+1] - p[i])`.
fn tcb_weights(k: Tcb) -> ((f32, f32), (f32, f32)) {
    let (t, c, b) = (k.tension, k.continuity, k.bias);
    let outgoing = (
        (1.0 - t) * (1.0 + c) * (1.0 + b) / 2.0,
        (1.0 - t) * (1.0 - c) * (1.0 - b) / 2.0,
    );
    let incoming = (
        (1.0 - t) * (1.0 - c) * (1.0 + b) / 2.0,
        (1.0 - t) * (1.0 + c) * (1.0 - b) / 2.0,
    );
    (outgoing, incoming)
}

/// `2 * span / total`, or 1 where keys share a time.
fn spacing(span: f32, total: f32) -> f32 {
    if total > 0.0 { 2.0 * span / total } else { 1.0 }
}

/// The segment `i` (keys `i`, `i+1`) holding `time` within the usable range,
/// and the local parameter. `times` is sorted.
fn locate(times: &[f32], time: f32) -> (usize, f32) {
    let n = times.len();
    if n == 1 {
        return (0, 0.0);
    }
    // Usable range: 2nd to second-to-last key (the whole list if too short).
    let (lo, hi) = if n >= 4 { (1, n - 2) } else { (0, n - 1) };
    // NOTE: max/min, not clamp: keys given by hand may be out of order or
    // NaN, and clamp panics on those.
    let t = time.max(times[lo]).min(times[hi]);
    let mut i = lo;
    while i + 1 < hi && times[i + 1] <= t {
        i += 1;
    }
    let span = times[i + 1] - times[i];
    let u = if span > 0.0 {
        ((t - times[i]) / span).clamp(0.0, 1.0)
    } else {
        1.0
    };
    (i, u)
}

/// Kochanek–Bartels interpolation of vector keys at `time`.
#[must_use]
pub fn interpolate_vec(keys: &[VecKey], time: f32) -> Option<Vec3> {
    let n = keys.len();
    if n == 0 {
        return None;
    }
    let times: Vec<f32> = keys.iter().map(|k| k.time).collect();
    let (i, u) = locate(&times, time);
    if n == 1 {
        return Some(keys[0].value);
    }
    let p = |j: isize| keys[j.clamp(0, n as isize - 1) as usize].value;
    let tm = |j: isize| keys[j.clamp(0, n as isize - 1) as usize].time;
    let ii = i as isize;
    let (p0, p1) = (p(ii), p(ii + 1));
    // Outgoing tangent at key i.
    let ((a, b), _) = tcb_weights(keys[i].tcb);
    let out_i = ((p0 - p(ii - 1)) * a + (p1 - p0) * b) * spacing(tm(ii + 1) - tm(ii), tm(ii + 1) - tm(ii - 1));
    // Incoming tangent at key i+1.
    let (_, (c, d)) = tcb_weights(keys[i + 1].tcb);
    let in_j = ((p1 - p0) * c + (p(ii + 2) - p1) * d) * spacing(tm(ii + 1) - tm(ii), tm(ii + 2) - tm(ii));
    let (u2, u3) = (u * u, u * u * u);
    let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
    let h10 = u3 - 2.0 * u2 + u;
    let h01 = -2.0 * u3 + 3.0 * u2;
    let h11 = u3 - u2;
    Some(p0 * h00 + out_i * h10 + p1 * h01 + in_j * h11)
}

/// Logarithm of a unit quaternion, as a vector (half-angle times axis).
fn qlog(q: Quat) -> Vec3 {
    let v = Vec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s < 1e-9 {
        return Vec3::ZERO;
    }
    let half = s.atan2(q.w);
    v * (half / s)
}

/// Exponential of a vector (pure quaternion) into a unit quaternion.
fn qexp(v: Vec3) -> Quat {
    let a = v.length();
    if a < 1e-9 {
        return Quat::IDENTITY;
    }
    let s = a.sin() / a;
    Quat::from_xyzw(v.x * s, v.y * s, v.z * s, a.cos())
}

/// The keys as unit quaternions, signs chosen so neighbours take the short way.
fn quaternions(keys: &[RotKey]) -> Vec<Quat> {
    let mut out: Vec<Quat> = Vec::with_capacity(keys.len());
    for k in keys {
        let axis = k.axis.try_normalize().unwrap_or(Vec3::Y);
        let mut q = Quat::from_axis_angle(axis, k.degrees.to_radians());
        if let Some(prev) = out.last()
            && prev.dot(q) < 0.0
        {
            q = -q;
        }
        out.push(q);
    }
    out
}

/// Squad interpolation with TCB tangents of rotation keys at `time`.
#[must_use]
pub fn interpolate_rot(keys: &[RotKey], time: f32) -> Option<Quat> {
    let n = keys.len();
    if n == 0 {
        return None;
    }
    let qs = quaternions(keys);
    let times: Vec<f32> = keys.iter().map(|k| k.time).collect();
    let (i, u) = locate(&times, time);
    if n == 1 {
        return Some(qs[0]);
    }
    let q = |j: isize| qs[j.clamp(0, n as isize - 1) as usize];
    let tm = |j: isize| times[j.clamp(0, n as isize - 1) as usize];
    let ii = i as isize;
    let (q0, q1) = (q(ii), q(ii + 1));
    // Log-space differences around keys i and i+1.
    let g_prev = qlog(q(ii - 1).inverse() * q0);
    let g = qlog(q0.inverse() * q1);
    let g_next = qlog(q1.inverse() * q(ii + 2));
    let ((a, b), _) = tcb_weights(keys[i].tcb);
    let out_i = (g_prev * a + g * b) * spacing(tm(ii + 1) - tm(ii), tm(ii + 1) - tm(ii - 1));
    let (_, (c, d)) = tcb_weights(keys[i + 1].tcb);
    let in_j = (g * c + g_next * d) * spacing(tm(ii + 1) - tm(ii), tm(ii + 2) - tm(ii));
    // Inner control points of squad.
    let s0 = q0 * qexp((out_i - g) * 0.5);
    let s1 = q1 * qexp((g - in_j) * 0.5);
    let outer = q0.slerp(q1, u);
    let inner = s0.slerp(s1, u);
    Some(outer.slerp(inner, 2.0 * u * (1.0 - u)).normalize())
}

impl Track {
    /// The node transform at `time`: translation * rotation * scale; parts
    /// without keys are the identity.
    #[must_use]
    pub fn matrix(&self, time: f32) -> Mat4 {
        let t = interpolate_vec(&self.translation, time).unwrap_or(Vec3::ZERO);
        let r = interpolate_rot(&self.rotation, time).unwrap_or(Quat::IDENTITY);
        let s = interpolate_vec(&self.scale, time).unwrap_or(Vec3::ONE);
        Mat4::from_scale_rotation_translation(s, r, t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vk(time: f32, x: f32, tcb: Tcb) -> VecKey {
        VecKey {
            time,
            value: Vec3::new(x, 0.0, 0.0),
            tcb,
        }
    }

    #[test]
    fn catmull_rom_reproduces_a_line_and_clamps_to_the_usable_range() {
        let keys: Vec<VecKey> = (0..6).map(|i| vk(i as f32, 2.0 * i as f32, Tcb::default())).collect();
        for t in [1.0f32, 1.3, 2.5, 3.9, 4.0] {
            let v = interpolate_vec(&keys, t).unwrap();
            assert!((v.x - 2.0 * t).abs() < 1e-5, "{t}: {v}");
        }
        // Clamped: before the 2nd key and after the second-to-last.
        assert!((interpolate_vec(&keys, -3.0).unwrap().x - 2.0).abs() < 1e-6);
        assert!((interpolate_vec(&keys, 99.0).unwrap().x - 8.0).abs() < 1e-6);
    }

    #[test]
    fn tcb_with_tension_continuity_bias_matches_a_hand_computation() {
        // Keys at t = 0, 1, 3, 4 with values 0, 1, 5, 2 (non-uniform spacing).
        let k = Tcb {
            tension: 0.5,
            continuity: -0.25,
            bias: 0.3,
        };
        let keys = vec![vk(0.0, 0.0, k), vk(1.0, 1.0, k), vk(3.0, 5.0, k), vk(4.0, 2.0, k)];
        // Segment 1 -> 3 at u = 0.5 (t = 2). By hand:
        // outgoing weights at key 1: a = 0.5*0.75*1.3/2 = 0.24375, b = 0.5*1.25*0.7/2 = 0.21875
        //   raw = 0.24375*(1-0) + 0.21875*(5-1) = 1.11875; spacing 2*(3-1)/(3-0) = 4/3 -> 1.4916667
        // incoming weights at key 3: c = 0.5*1.25*1.3/2 = 0.40625, d = 0.5*0.75*0.7/2 = 0.13125
        //   raw = 0.40625*4 + 0.13125*(2-5) = 1.23125; spacing 2*(3-1)/(4-1) = 4/3 -> 1.6416667
        // Hermite at u = 0.5: 0.5*p0 + 0.125*m0 + 0.5*p1 - 0.125*m1
        //   = 0.5 + 0.18645833 + 2.5 - 0.20520833 = 2.98125
        let v = interpolate_vec(&keys, 2.0).unwrap();
        assert!((v.x - 2.981_25).abs() < 1e-5, "{}", v.x);
    }

    #[test]
    fn squad_follows_a_wheel_through_many_turns() {
        // A wheel spinning 90 degrees per second about -z, keys up to 1440 degrees.
        let keys: Vec<RotKey> = (0..=16)
            .map(|i| RotKey {
                time: i as f32,
                axis: Vec3::new(0.0, 0.0, -1.0),
                degrees: 90.0 * i as f32,
                tcb: Tcb::default(),
            })
            .collect();
        for t in [1.0f32, 2.5, 4.25, 7.5, 12.9, 15.0] {
            let q = interpolate_rot(&keys, t).unwrap();
            let expected = Quat::from_axis_angle(Vec3::new(0.0, 0.0, -1.0), (90.0 * t).to_radians());
            assert!(q.dot(expected).abs() > 1.0 - 1e-5, "t={t}: {q} vs {expected}");
        }
    }

    #[test]
    fn non_unit_axes_and_duplicate_times_are_handled() {
        let tcb = Tcb::default();
        let keys = vec![
            RotKey {
                time: 0.0,
                axis: Vec3::new(0.0, 1.05, 0.0),
                degrees: 0.0,
                tcb,
            },
            RotKey {
                time: 1.0,
                axis: Vec3::new(0.0, 0.97, 0.0),
                degrees: 10.0,
                tcb,
            },
            RotKey {
                time: 1.0,
                axis: Vec3::new(0.0, 1.0, 0.0),
                degrees: 20.0,
                tcb,
            },
            RotKey {
                time: 2.0,
                axis: Vec3::new(0.0, 1.0, 0.0),
                degrees: 30.0,
                tcb,
            },
            RotKey {
                time: 3.0,
                axis: Vec3::new(0.0, 1.0, 0.0),
                degrees: 40.0,
                tcb,
            },
        ];
        for t in [0.5f32, 1.0, 1.5, 2.0, 2.5] {
            let q = interpolate_rot(&keys, t).unwrap();
            assert!(q.is_finite() && (q.length() - 1.0).abs() < 1e-5, "t={t}: {q}");
        }
        let tr = Track {
            rotation: keys,
            ..Track::default()
        };
        assert!(tr.matrix(1.5).is_finite());
    }
}
