//! A frame's time split by phase, from clocks in the renderer that cost one
//! predictable branch each when off ([`crate::Renderer::set_phase_timing`]).
//! Phases are summed over the render threads, so on one thread they add up
//! to the frame's render time, less the tile loop's own bookkeeping.
//!
//! The clock is `quanta`'s: the CPU's time-stamp counter scaled to
//! nanoseconds where it runs at a constant rate (the OS clock elsewhere).
//! A kitchen GL-like packet takes six readings; `std::time::Instant` cost
//! 26 ns a reading on the bench machine (a vDSO call), `quanta` 10 ns.

use quanta::Instant;

/// Nanoseconds spent in each phase of a frame, summed over the render
/// threads. Shadow queries include making the shadow rays; the light loop
/// includes making the bounce rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PhaseTimes {
    /// Camera rays.
    pub camera_ns: u64,
    /// First-hit queries of camera rays.
    pub primary_ns: u64,
    /// Shadow rays towards the lights, made and traced.
    pub shadow_ns: u64,
    /// Closest-hit queries of reflection and refraction rays.
    pub bounce_ns: u64,
    /// Surface reconstruction at the hits (point, normals, texture
    /// coordinates, offsets, ray cones), one-sided pass-through included.
    pub surface_ns: u64,
    /// Texture lookups (level of detail and filtering).
    pub textures_ns: u64,
    /// The light loop with its highlight powers, and the bounce rays' set-up.
    pub lights_ns: u64,
    /// Assembling the tiles into the image.
    pub image_ns: u64,
}

/// One phase of [`PhaseTimes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Phase {
    Camera,
    Primary,
    Shadow,
    Bounce,
    Surface,
    Textures,
    Lights,
}

impl PhaseTimes {
    /// Adds `ns` to `phase`.
    #[inline]
    pub(crate) fn add(&mut self, phase: Phase, ns: u64) {
        let slot = match phase {
            Phase::Camera => &mut self.camera_ns,
            Phase::Primary => &mut self.primary_ns,
            Phase::Shadow => &mut self.shadow_ns,
            Phase::Bounce => &mut self.bounce_ns,
            Phase::Surface => &mut self.surface_ns,
            Phase::Textures => &mut self.textures_ns,
            Phase::Lights => &mut self.lights_ns,
        };
        *slot += ns;
    }

    /// Adds every phase of `other`.
    pub fn merge(&mut self, other: &Self) {
        self.camera_ns += other.camera_ns;
        self.primary_ns += other.primary_ns;
        self.shadow_ns += other.shadow_ns;
        self.bounce_ns += other.bounce_ns;
        self.surface_ns += other.surface_ns;
        self.textures_ns += other.textures_ns;
        self.lights_ns += other.lights_ns;
        self.image_ns += other.image_ns;
    }

    /// Every phase with its name, in frame order: camera, primary, shadow,
    /// bounce, surface, textures, light loop, image.
    #[must_use]
    pub fn named(&self) -> [(&'static str, u64); 8] {
        [
            ("camera", self.camera_ns),
            ("primary", self.primary_ns),
            ("shadow", self.shadow_ns),
            ("bounce", self.bounce_ns),
            ("surface", self.surface_ns),
            ("textures", self.textures_ns),
            ("light loop", self.lights_ns),
            ("image", self.image_ns),
        ]
    }

    /// The ray queries: primary, shadow and bounce.
    #[must_use]
    pub fn queries_ns(&self) -> u64 {
        self.primary_ns + self.shadow_ns + self.bounce_ns
    }

    /// Shading: surfaces, textures and the light loop.
    #[must_use]
    pub fn shading_ns(&self) -> u64 {
        self.surface_ns + self.textures_ns + self.lights_ns
    }

    /// Every phase.
    #[must_use]
    pub fn total_ns(&self) -> u64 {
        self.camera_ns + self.queries_ns() + self.shading_ns() + self.image_ns
    }
}

/// A render thread's clock: when on, each phase's span is added to `times`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PhaseClock {
    pub on: bool,
    pub times: PhaseTimes,
}

impl PhaseClock {
    /// The start of a span: `None` without a read of the clock unless `ON`
    /// (callers pass `ON` as a constant, so that the untimed code has no
    /// trace of the clock; the caller chose `ON` from [`PhaseClock::on`]).
    #[inline]
    pub(crate) fn start<const ON: bool>() -> Option<Instant> {
        if ON { Some(Instant::now()) } else { None }
    }

    /// Ends the span begun at `since` as `phase`; returns its end, the start
    /// of the next span.
    #[inline]
    pub(crate) fn stop<const ON: bool>(&mut self, since: Option<Instant>, phase: Phase) -> Option<Instant> {
        if !ON {
            return None;
        }
        let since = since?;
        let now = Instant::now();
        self.times
            .add(phase, u64::try_from((now - since).as_nanos()).unwrap_or(u64::MAX));
        Some(now)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_idle_clock_records_nothing_and_a_running_one_every_phase() {
        let mut off = PhaseClock::default();
        let t = PhaseClock::start::<false>();
        assert!(t.is_none() && off.stop::<false>(t, Phase::Primary).is_none());
        assert_eq!(off.times, PhaseTimes::default());
        let mut on = PhaseClock {
            on: true,
            ..PhaseClock::default()
        };
        let mut t = PhaseClock::start::<true>();
        for phase in [
            Phase::Camera,
            Phase::Primary,
            Phase::Shadow,
            Phase::Bounce,
            Phase::Surface,
            Phase::Textures,
            Phase::Lights,
        ] {
            std::thread::sleep(std::time::Duration::from_micros(50));
            t = on.stop::<true>(t, phase);
        }
        let p = on.times;
        for (name, ns) in [
            ("camera", p.camera_ns),
            ("primary", p.primary_ns),
            ("shadow", p.shadow_ns),
            ("bounce", p.bounce_ns),
            ("surface", p.surface_ns),
            ("textures", p.textures_ns),
            ("lights", p.lights_ns),
        ] {
            // Each span held a sleep of 50 µs: a lower bound, not a speed.
            assert!(ns >= 50_000, "{name}: {ns} ns");
        }
        assert_eq!(p.total_ns(), p.camera_ns + p.queries_ns() + p.shading_ns());
        assert_eq!(p.named().iter().map(|(_, ns)| ns).sum::<u64>(), p.total_ns());
        let mut sum = PhaseTimes::default();
        sum.merge(&p);
        sum.merge(&p);
        assert_eq!(sum.total_ns(), 2 * p.total_ns());
    }
}
