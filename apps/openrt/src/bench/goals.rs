//! The goals the report judges and the paper's figures, as data in one
//! place; `targets` turns a run's results into verdicts.

use openrt_core::{Accel, Backend};

use super::results::{Results, Row};

/// The paper's figures (Wald, Benthin & Slusallek 2003), fps for 1, 2, 4, 8
/// and 16 rendering clients of 2 CPUs each (2 to 32 CPUs); NaN where the
/// paper gives no figure (the robots: only the ends of the range).
pub(super) const PAPER: &[(&str, &str, [f64; 5])] = &[
    ("robots", "Whitted", [0.24, f64::NAN, f64::NAN, f64::NAN, 4.0]),
    ("robots", "GL-like", [1.25, f64::NAN, f64::NAN, f64::NAN, 20.0]),
    ("kitchen", "Whitted", [0.25, 0.5, 1.05, 2.0, 4.0]),
    ("kitchen", "GL-like", [1.7, 3.4, 6.8, 13.6, 26.0]),
    ("terrain", "Whitted", [0.3, 0.6, 1.19, 2.29, 4.26]),
    ("museum1k", "Whitted", [0.6, 1.2, 2.4, 4.8, 9.3]),
    ("museum4k", "Whitted", [0.55, 1.1, 2.2, 4.2, 2.5]),
    ("museum16k", "Whitted", [0.45, 0.9, 1.65, 0.98, 0.53]),
];

/// Kitchen, Whitted depth 3: the paper's 32-CPU frame rate.
pub(super) const KITCHEN_WHITTED_FPS: f64 = 4.3;
/// Kitchen, OpenGL-like: the paper's 32-CPU frame rate.
pub(super) const KITCHEN_GL_FPS: f64 = 26.0;
/// Museum16k: the moving triangles' rebuild or refit in a played frame
/// (the frames table's moving-objects column), at most (ms).
pub(super) const MUSEUM16K_REBUILD_MS: f64 = 2.0;
/// Embree's LOW build (or REFIT) time over our refit time, at least.
pub(super) const REFIT_VS_EMBREE_LOW: f64 = 1.0;
/// Render time with refitted structures over freshly built ones, at most.
pub(super) const REFIT_RENDER_RATIO: f64 = 1.05;
/// Render thread scaling from 1 to 2 threads (kitchen Whitted), at least.
pub(super) const THREAD_SCALING_1_2: f64 = 1.9;
/// Packets against single rays, ray queries alone, at least.
pub(super) const PACKETS_VS_SINGLE: f64 = 3.0;
/// Robots: trilinear against bilinear textures, error ratio at most ...
pub(super) const TRILINEAR_ERROR_RATIO: f64 = 0.5;
/// ... for a frame time ratio at most.
pub(super) const TRILINEAR_TIME_RATIO: f64 = 1.15;
/// Kitchen, OpenGL-like: time outside the ray queries per pixel, at most (ns).
pub(super) const KITCHEN_GL_OUTSIDE_QUERIES_NS: f64 = 95.0;
/// Whitted frames: shading's share of the frame, at most (per cent).
pub(super) const WHITTED_SHADING_SHARE_PCT: f64 = 15.0;
/// A skinned glTF mesh of about 100k triangles: skinning plus the refit
/// per frame on the most threads, at most (ms).
pub(super) const SKIN_REFIT_100K_MS: f64 = 5.0;
/// The default object structure (`Accel::default()`) is the faster one on
/// at least this share of the frames table's rows (per cent): issue 39's
/// rule that the default follows the bench.
pub(super) const DEFAULT_ACCEL_SHARE_PCT: f64 = 50.0;
/// Samples per pixel of the speed-against-error reference.
pub(super) const REFERENCE_SPP: u32 = 64;
/// PSNR that counts as "close to the reference" in the report.
pub(super) const CLOSE_DB: f64 = 35.0;

/// One goal of the run and its verdict.
pub(super) struct Target {
    pub(super) what: String,
    pub(super) got: Option<f64>,
    pub(super) goal: f64,
    pub(super) unit: &'static str,
    /// The goal is a minimum (else a maximum).
    pub(super) higher: bool,
}

impl Target {
    /// `Some(true)` when met, `None` when not measured.
    pub(super) fn met(&self) -> Option<bool> {
        self.got
            .map(|g| if self.higher { g >= self.goal } else { g <= self.goal })
    }

    /// The report's line.
    pub(super) fn line(&self) -> String {
        let (what, goal, unit) = (&self.what, self.goal, self.unit);
        match (self.got, self.met()) {
            (Some(g), Some(true)) => format!("- {what}: {g:.2} {unit} (goal {goal} {unit}): met"),
            (Some(g), _) => format!(
                "- {what}: {g:.2} {unit} (goal {goal} {unit}): **not met**, {:.2}x short",
                if self.higher { goal / g } else { g / goal }
            ),
            (None, _) => format!("- {what}: not measured in this run"),
        }
    }
}

/// "met" or "**not met**".
pub(super) fn verdict(met: bool) -> &'static str {
    if met { "met" } else { "**not met**" }
}

/// The run's frame rate of `scene` in `mode` (default backend) on the most threads.
fn fps(rows: &[&Row], scene: &str, mode: &str) -> Option<f64> {
    rows.iter()
        .filter(|r| r.scene == scene && r.mode == mode)
        .max_by_key(|r| r.threads)
        .map(|r| r.fps())
}

/// The goals judged from `results`, in the report's order.
pub(super) fn targets(results: &Results, default_backend: &str) -> Vec<Target> {
    let rows: Vec<&Row> = results.frames.iter().filter(|r| r.backend == default_backend).collect();
    let target = |what: String, got: Option<f64>, goal: f64, unit: &'static str, higher: bool| Target {
        what,
        got,
        goal,
        unit,
        higher,
    };
    let mut out = vec![
        target(
            "kitchen full Whitted".into(),
            fps(&rows, "kitchen", "Whitted"),
            KITCHEN_WHITTED_FPS,
            "fps",
            true,
        ),
        target(
            "kitchen GL-like".into(),
            fps(&rows, "kitchen", "GL-like"),
            KITCHEN_GL_FPS,
            "fps",
            true,
        ),
        target(
            "museum16k moving triangles rebuilt or refitted, per frame (frames table, fewest threads)".into(),
            rows.iter().find(|r| r.scene == "museum16k").map(|r| r.fast_ms),
            MUSEUM16K_REBUILD_MS,
            "ms",
            false,
        ),
    ];
    for r in &results.rebuilds {
        out.push(target(
            format!(
                "{} moving triangles, Embree LOW build time / our refit time (rebuild table)",
                r.scene
            ),
            r.embree_ms.map(|e| e / r.refit_ms.max(1e-9)),
            REFIT_VS_EMBREE_LOW,
            "x",
            true,
        ));
        out.push(target(
            format!(
                "{} moving triangles, Embree's LOW build or REFIT, the faster, / our BVH refit (rebuild table)",
                r.scene
            ),
            r.embree_ms
                .zip(r.embree_refit_ms)
                .map(|(e, f)| e.min(f) / r.bvh_refit_ms.max(1e-9)),
            REFIT_VS_EMBREE_LOW,
            "x",
            true,
        ));
    }
    for b in &results.builders {
        for (what, ratio) in [("kd-trees", b.kd_ratio), ("BVHs", b.bvh_ratio)] {
            out.push(target(
                format!(
                    "{} Whitted render with refitted {what} / with {what} built afresh (builders table, median of the per-frame ratios)",
                    b.scene
                ),
                Some(ratio),
                REFIT_RENDER_RATIO,
                "x",
                false,
            ));
        }
    }
    let default_phase = |scene: &str, mode: &str| {
        results
            .phases
            .iter()
            .find(|p| p.scene == scene && p.mode == mode && p.backend == default_backend)
    };
    out.push(target(
        "kitchen GL-like time outside the ray queries per pixel (phase table, one thread)".into(),
        default_phase("kitchen", "GL-like").map(super::results::PhaseRow::outside_queries_ns_per_pixel),
        KITCHEN_GL_OUTSIDE_QUERIES_NS,
        "ns",
        false,
    ));
    for p in results
        .phases
        .iter()
        .filter(|p| p.mode == "Whitted" && p.backend == default_backend)
    {
        out.push(target(
            format!("{} Whitted: shading's share of the frame (phase table)", p.scene),
            Some(100.0 * p.shading_share()),
            WHITTED_SHADING_SHARE_PCT,
            "%",
            false,
        ));
    }
    let most = results.deforming.iter().map(|d| d.threads).max();
    for d in results
        .deforming
        .iter()
        .filter(|d| Some(d.threads) == most && d.triangles.abs_diff(100_000) < 5_000)
    {
        out.push(target(
            format!(
                "skinned glTF mesh of {} triangles ({}), skinning + refit per frame on {} threads (deforming table)",
                d.triangles, d.accel, d.threads
            ),
            Some(d.skin_refit_ms()),
            SKIN_REFIT_100K_MS,
            "ms",
            false,
        ));
    }
    out.push(default_accel_target(results));
    let kitchen_whitted = |t: usize| {
        rows.iter()
            .find(|r| r.scene == "kitchen" && r.mode == "Whitted" && r.threads == t)
            .map(|r| r.render_ms)
    };
    out.push(target(
        "render thread scaling 1 -> 2 (kitchen Whitted)".into(),
        kitchen_whitted(1).zip(kitchen_whitted(2)).map(|(a, b)| a / b),
        THREAD_SCALING_1_2,
        "x",
        true,
    ));
    out
}

/// The share of the frames table's rows (scene, mode, threads) on which
/// the default object structure's packets give at least the other's frame
/// rate (both structures played frame by frame in turn, `measure.rs`).
fn default_accel_share(frames: &[Row]) -> Option<f64> {
    let default = Accel::default();
    let other = match default {
        Accel::Kd => Accel::Bvh,
        Accel::Bvh => Accel::Kd,
    };
    let (mut rows, mut wins) = (0u32, 0u32);
    for d in frames.iter().filter(|r| r.backend == Backend::Packets.label(default)) {
        if let Some(o) = frames.iter().find(|o| {
            o.backend == Backend::Packets.label(other)
                && o.scene == d.scene
                && o.mode == d.mode
                && o.threads == d.threads
        }) {
            rows += 1;
            wins += u32::from(d.fps() >= o.fps());
        }
    }
    (rows > 0).then(|| 100.0 * f64::from(wins) / f64::from(rows))
}

/// The verdict on the default object structure ([`DEFAULT_ACCEL_SHARE_PCT`]).
fn default_accel_target(results: &Results) -> Target {
    let default = Accel::default().name();
    Target {
        what: format!(
            "frame rows (frames table) on which the default object structure, `{default}`, is at least as fast as the other (else the default should change)"
        ),
        got: default_accel_share(&results.frames),
        goal: DEFAULT_ACCEL_SHARE_PCT,
        unit: "%",
        higher: true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows pair by scene, mode and threads; ties count for the default;
    /// other backends and unpaired rows are not counted.
    #[test]
    fn the_default_structure_share_counts_paired_rows() {
        let (d, o) = (
            Backend::Packets.label(Accel::default()),
            Backend::Packets.label(Accel::Kd),
        );
        assert_eq!(d, "bvh", "the test names the default");
        let rows = vec![
            Row::sample("a", d, 1, 10.0),
            Row::sample("a", o, 1, 12.0),
            Row::sample("a", d, 2, 10.0),
            Row::sample("a", o, 2, 10.0),
            Row::sample("b", d, 1, 10.0),
            Row::sample("b", o, 1, 9.0),
            Row::sample("c", d, 1, 1.0),
            Row::sample("c", "embree-packet", 1, 100.0),
        ];
        let share = default_accel_share(&rows).expect("three pairs");
        assert!((share - 200.0 / 3.0).abs() < 1e-9, "{share}");
        assert_eq!(default_accel_share(&rows[6..]), None);
        let results = Results {
            frames: vec![Row::sample("b", d, 1, 10.0), Row::sample("b", o, 1, 9.0)],
            ..Results::default()
        };
        let t = default_accel_target(&results);
        assert_eq!(t.met(), Some(false), "{}", t.line());
    }

    #[test]
    fn targets_judge_minimums_and_maximums() {
        let t = |got, higher| Target {
            what: "x".into(),
            got,
            goal: 2.0,
            unit: "ms",
            higher,
        };
        assert_eq!(t(Some(2.0), true).met(), Some(true));
        assert_eq!(t(Some(1.0), true).met(), Some(false));
        assert_eq!(t(Some(1.0), false).met(), Some(true));
        assert_eq!(t(Some(3.0), false).met(), Some(false));
        assert_eq!(t(None, true).met(), None);
        assert!(t(Some(1.0), true).line().contains("**not met**, 2.00x short"));
        assert!(t(Some(3.0), false).line().contains("1.50x short"));
        assert!(t(None, false).line().contains("not measured"));
    }
}
