//! glTF node animation: samplers of translation, rotation and scale keys
//! with STEP, LINEAR (rotations by slerp) and CUBICSPLINE interpolation
//! (glTF 2.0 specification, appendix C), checked when loaded.

use glam::{Quat, Vec3, Vec4};

/// How a sampler interpolates between its keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Interpolation {
    Step,
    Linear,
    CubicSpline,
}

impl Interpolation {
    /// Output values per key: three for cubic splines (in-tangent, value,
    /// out-tangent), else one.
    fn values_per_key(self) -> usize {
        if self == Self::CubicSpline { 3 } else { 1 }
    }
}

/// Key times: at least one, finite, strictly increasing.
fn check_times(times: &[f32]) -> Result<(), String> {
    if times.is_empty() {
        return Err("a sampler has no keys".into());
    }
    if let Some(t) = times.iter().find(|t| !t.is_finite()) {
        return Err(format!("key time {t} is not finite"));
    }
    if let Some((a, b)) = times.windows(2).map(|w| (w[0], w[1])).find(|(a, b)| b <= a) {
        return Err(format!("key times must increase: {a} is followed by {b}"));
    }
    Ok(())
}

/// `per_key` output values for each of `keys` keys (`what` names them in
/// the message), all finite.
fn check_values(keys: usize, per_key: usize, len: usize, what: &str, finite: bool) -> Result<(), String> {
    if len != keys * per_key {
        return Err(format!(
            "{keys} keys{what} need {} output values, the sampler has {len}",
            keys * per_key
        ));
    }
    if !finite {
        return Err("an output value is not finite".into());
    }
    Ok(())
}

/// Where a time falls among checked key times.
enum Span {
    /// Before the first key, after the last, or a single key: that key.
    Key(usize),
    /// `times[k] <= t < times[k + 1]`, at fraction `s` of the interval `dt`.
    Between { k: usize, s: f32, dt: f32 },
}

fn span(times: &[f32], t: f32) -> Span {
    let n = times.len();
    if n == 1 || t <= times[0] {
        return Span::Key(0);
    }
    if t >= times[n - 1] {
        return Span::Key(n - 1);
    }
    let k = times.partition_point(|&x| x <= t) - 1;
    let dt = times[k + 1] - times[k];
    Span::Between {
        k,
        s: (t - times[k]) / dt,
        dt,
    }
}

/// The node property a channel animates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Property {
    Translation,
    Rotation,
    Scale,
}

/// One animation channel: a node's property over time. Values are four
/// wide (rotations as `x, y, z, w`; vectors with a zero `w`); a cubic
/// spline keeps three per key (in-tangent, value, out-tangent).
#[derive(Clone, Debug)]
pub(crate) struct Channel {
    pub node: usize,
    pub property: Property,
    pub interpolation: Interpolation,
    pub times: Vec<f32>,
    pub values: Vec<Vec4>,
}

impl Channel {
    /// Checks the keys: at least one, finite, strictly increasing times,
    /// finite values, one value per key (three for cubic splines). The
    /// error states the rule broken.
    pub fn check(&self) -> Result<(), String> {
        check_times(&self.times)?;
        check_values(
            self.times.len(),
            self.interpolation.values_per_key(),
            self.values.len(),
            "",
            self.values.iter().all(|v| v.is_finite()),
        )
    }

    /// The last key's time.
    pub fn end(&self) -> f32 {
        self.times.last().copied().unwrap_or(0.0)
    }

    /// The value at `t` (clamped to the keys' range).
    pub fn sample(&self, t: f32) -> Vec4 {
        let value = |k: usize| match self.interpolation {
            Interpolation::CubicSpline => self.values[3 * k + 1],
            _ => self.values[k],
        };
        let (k, s, dt) = match span(&self.times, t) {
            Span::Key(k) => return self.finish(value(k)),
            Span::Between { k, s, dt } => (k, s, dt),
        };
        let v = match self.interpolation {
            Interpolation::Step => value(k),
            Interpolation::Linear => {
                if self.property == Property::Rotation {
                    let (a, b) = (
                        Quat::from_vec4(value(k)).normalize(),
                        Quat::from_vec4(value(k + 1)).normalize(),
                    );
                    Vec4::from(a.slerp(b, s))
                } else {
                    value(k).lerp(value(k + 1), s)
                }
            }
            Interpolation::CubicSpline => {
                // Hermite: p0, its out-tangent, p1, its in-tangent, scaled by dt.
                let (p0, m0) = (self.values[3 * k + 1], self.values[3 * k + 2] * dt);
                let (p1, m1) = (self.values[3 * (k + 1) + 1], self.values[3 * (k + 1)] * dt);
                let (s2, s3) = (s * s, s * s * s);
                p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                    + m0 * (s3 - 2.0 * s2 + s)
                    + p1 * (-2.0 * s3 + 3.0 * s2)
                    + m1 * (s3 - s2)
            }
        };
        self.finish(v)
    }

    /// Rotations come out as unit quaternions.
    fn finish(&self, v: Vec4) -> Vec4 {
        if self.property == Property::Rotation {
            Vec4::from(Quat::from_vec4(v).normalize())
        } else {
            v
        }
    }
}

/// A morph-weight channel: `width` weights per key (three times that per
/// key for cubic splines: in-tangents, values, out-tangents).
#[derive(Clone, Debug)]
pub(crate) struct WeightChannel {
    pub node: usize,
    pub interpolation: Interpolation,
    pub times: Vec<f32>,
    pub values: Vec<f32>,
    pub width: usize,
}

impl WeightChannel {
    /// Checks the keys as [`Channel::check`] does, with `width` values per key.
    pub fn check(&self) -> Result<(), String> {
        check_times(&self.times)?;
        if self.width == 0 {
            return Err("morph weights animate a mesh without morph targets".into());
        }
        check_values(
            self.times.len(),
            self.width * self.interpolation.values_per_key(),
            self.values.len(),
            &format!(" of {} morph weights", self.width),
            self.values.iter().all(|v| v.is_finite()),
        )
    }

    /// The last key's time.
    pub fn end(&self) -> f32 {
        self.times.last().copied().unwrap_or(0.0)
    }

    /// The weights at `t` (clamped to the keys' range).
    pub fn sample(&self, t: f32) -> Vec<f32> {
        let w = self.width;
        let cubic = self.interpolation == Interpolation::CubicSpline;
        // Key k's values, in-tangents and out-tangents.
        let part = |k: usize, which: usize| {
            let start = if cubic { (3 * k + which) * w } else { k * w };
            &self.values[start..start + w]
        };
        let value = |k: usize| part(k, 1).to_vec();
        let (k, s, dt) = match span(&self.times, t) {
            Span::Key(k) => return value(k),
            Span::Between { k, s, dt } => (k, s, dt),
        };
        match self.interpolation {
            Interpolation::Step => value(k),
            Interpolation::Linear => value(k)
                .iter()
                .zip(value(k + 1))
                .map(|(a, b)| a + (b - a) * s)
                .collect(),
            Interpolation::CubicSpline => {
                let (s2, s3) = (s * s, s * s * s);
                (0..w)
                    .map(|i| {
                        let (p0, m0) = (part(k, 1)[i], part(k, 2)[i] * dt);
                        let (p1, m1) = (part(k + 1, 1)[i], part(k + 1, 0)[i] * dt);
                        p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                            + m0 * (s3 - 2.0 * s2 + s)
                            + p1 * (-2.0 * s3 + 3.0 * s2)
                            + m1 * (s3 - s2)
                    })
                    .collect()
            }
        }
    }
}

/// A node's local transform as translation, rotation and scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Trs {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Trs {
    /// This transform with `channel`'s value at `t` in place of its property.
    pub fn with(mut self, channel: &Channel, t: f32) -> Self {
        let v = channel.sample(t);
        match channel.property {
            Property::Translation => self.translation = v.truncate(),
            Property::Rotation => self.rotation = Quat::from_vec4(v),
            Property::Scale => self.scale = v.truncate(),
        }
        self
    }

    /// The matrix `T * R * S`.
    pub fn matrix(&self) -> glam::Mat4 {
        glam::Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(property: Property, interpolation: Interpolation, times: &[f32], values: &[[f32; 4]]) -> Channel {
        Channel {
            node: 0,
            property,
            interpolation,
            times: times.to_vec(),
            values: values.iter().map(|&v| Vec4::from_array(v)).collect(),
        }
    }

    #[test]
    fn step_and_linear_keys_are_held_and_blended() {
        let keys = [[0.0, 0.0, 0.0, 0.0], [2.0, 4.0, -2.0, 0.0], [2.0, 0.0, 0.0, 0.0]];
        let step = channel(Property::Translation, Interpolation::Step, &[0.0, 1.0, 3.0], &keys);
        step.check().unwrap();
        assert_eq!(step.sample(0.99), Vec4::ZERO);
        assert_eq!(step.sample(1.0), Vec4::new(2.0, 4.0, -2.0, 0.0));
        assert_eq!(step.sample(2.5), Vec4::new(2.0, 4.0, -2.0, 0.0));
        assert_eq!(step.sample(-5.0), Vec4::ZERO, "before the first key: the first value");
        assert_eq!(
            step.sample(9.0),
            Vec4::new(2.0, 0.0, 0.0, 0.0),
            "after the last: the last"
        );
        let lin = channel(Property::Translation, Interpolation::Linear, &[0.0, 1.0, 3.0], &keys);
        assert_eq!(lin.sample(0.5), Vec4::new(1.0, 2.0, -1.0, 0.0));
        assert_eq!(lin.sample(2.0), Vec4::new(2.0, 2.0, -1.0, 0.0));
        assert_eq!(lin.end(), 3.0);
    }

    #[test]
    fn rotations_are_slerped_to_unit_quaternions() {
        let a = Quat::IDENTITY;
        let b = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let c = channel(
            Property::Rotation,
            Interpolation::Linear,
            &[0.0, 1.0],
            &[a.to_array(), b.to_array()],
        );
        let half = Quat::from_vec4(c.sample(0.5));
        let want = Quat::from_rotation_y(std::f32::consts::FRAC_PI_4);
        assert!(half.angle_between(want) < 1e-5, "{half:?}");
        assert!((half.length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn cubic_splines_pass_through_their_keys_with_their_tangents() {
        // Two keys 2 s apart; tangents (per second) 1 and 0 on x.
        let c = channel(
            Property::Translation,
            Interpolation::CubicSpline,
            &[0.0, 2.0],
            &[
                [0.0; 4],
                [0.0, 0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0, 0.0],
                [0.0; 4],
                [1.0, 0.0, 0.0, 0.0],
                [0.0; 4],
            ],
        );
        c.check().unwrap();
        assert_eq!(c.sample(0.0).x, 0.0);
        assert_eq!(c.sample(2.0).x, 1.0);
        // Hermite at s = 1/2: 0.5 * p1 + (1/8) * dt * m0 = 0.5 + 0.25.
        assert!((c.sample(1.0).x - 0.75).abs() < 1e-6, "{}", c.sample(1.0).x);
        // The slope at the start is the out-tangent: 1 per second.
        let slope = c.sample(1e-3).x / 1e-3;
        assert!((slope - 1.0).abs() < 1e-2, "{slope}");
    }

    #[test]
    fn morph_weights_are_sampled_per_target() {
        let c = WeightChannel {
            node: 0,
            interpolation: Interpolation::Linear,
            times: vec![0.0, 2.0],
            values: vec![0.0, 1.0, 1.0, 0.0],
            width: 2,
        };
        c.check().unwrap();
        assert_eq!(c.sample(0.5), vec![0.25, 0.75]);
        assert_eq!(c.sample(5.0), vec![1.0, 0.0]);
        let step = WeightChannel {
            interpolation: Interpolation::Step,
            ..c.clone()
        };
        assert_eq!(step.sample(1.99), vec![0.0, 1.0]);
        // A cubic spline with zero tangents eases: 1/2 at the middle.
        let spline = WeightChannel {
            interpolation: Interpolation::CubicSpline,
            values: vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0],
            ..c.clone()
        };
        spline.check().unwrap();
        assert_eq!(spline.sample(1.0), vec![0.5, 0.5]);
        let short = WeightChannel {
            values: vec![0.0; 3],
            ..c.clone()
        };
        assert!(short.check().unwrap_err().contains("need 4 output values"));
        let none = WeightChannel { width: 0, ..c };
        assert!(none.check().unwrap_err().contains("without morph targets"));
    }

    #[test]
    fn broken_samplers_are_refused_with_the_rule() {
        let v = [[0.0; 4], [1.0, 0.0, 0.0, 0.0]];
        let bad = [
            (vec![0.0, 0.0], "must increase"),
            (vec![1.0, 0.5], "must increase"),
            (vec![0.0, f32::NAN], "not finite"),
            (vec![0.0], "need 1 output values, the sampler has 2"),
            (vec![], "no keys"),
        ];
        for (times, rule) in bad {
            let c = channel(Property::Scale, Interpolation::Linear, &times, &v);
            let e = c.check().unwrap_err();
            assert!(e.contains(rule), "{times:?}: {e}");
        }
        let nan = channel(
            Property::Scale,
            Interpolation::Linear,
            &[0.0, 1.0],
            &[[0.0; 4], [f32::NAN; 4]],
        );
        assert!(nan.check().unwrap_err().contains("not finite"));
        let spline = channel(Property::Scale, Interpolation::CubicSpline, &[0.0, 1.0], &v);
        assert!(spline.check().unwrap_err().contains("need 6"));
    }
}
