//! What a bench run measured, as typed values: the measurement functions
//! (`measure.rs`) return them and the report (`report.rs`) renders them.

/// Per scene, mode, backend and thread count: the medians over the sampled frames.
pub(super) struct Row {
    pub(super) scene: String,
    pub(super) mode: &'static str,
    pub(super) backend: &'static str,
    pub(super) threads: usize,
    pub(super) commit_ms: f64,
    pub(super) toplevel_ms: f64,
    pub(super) fast_ms: f64,
    pub(super) promotions: usize,
    pub(super) render_ms: f64,
    pub(super) rays: f64,
    pub(super) triangles: usize,
    pub(super) instances: usize,
}

impl Row {
    /// A row of the tests: `render_ms` on `threads`, nothing else spent.
    #[cfg(test)]
    pub(super) fn sample(scene: &str, backend: &'static str, threads: usize, render_ms: f64) -> Self {
        Self {
            scene: scene.into(),
            mode: "Whitted",
            backend,
            threads,
            commit_ms: 0.0,
            toplevel_ms: 0.0,
            fast_ms: 0.0,
            promotions: 0,
            render_ms,
            rays: 0.0,
            triangles: 0,
            instances: 0,
        }
    }

    /// Frames per second: 1000 / (commit + render).
    pub(super) fn fps(&self) -> f64 {
        1000.0 / (self.commit_ms + self.render_ms)
    }
}

/// How one backend's image of a frame differs from the `kd` backend's.
pub(super) struct ImageDiff {
    pub(super) scene: String,
    pub(super) mode: &'static str,
    pub(super) backend: &'static str,
    /// The RGB bytes are identical.
    pub(super) identical: bool,
    /// Share of pixels with a channel off by more than 8/255.
    pub(super) off_share: f64,
}

/// One ray kind of a scene's middle frame, queries alone (Mrays/s).
pub(super) struct KindRow {
    pub(super) scene: String,
    pub(super) kind: &'static str,
    pub(super) single: f64,
    pub(super) packet: f64,
    /// Embree one by one and in packets (builds with `--features embree`).
    pub(super) embree: Option<(f64, f64)>,
    /// The same queries with BVHs under the instances: one by one, packets.
    pub(super) bvh: (f64, f64),
    /// Kd objects under each top level: single rays with the BSP and the
    /// BVH, then packets with the BSP and the BVH (Mrays/s).
    pub(super) top: [f64; 4],
    /// The top level the default (`TopLevel::Auto`) chose, and the instance count.
    pub(super) top_default: (&'static str, usize),
    pub(super) rays: usize,
}

/// One setting of the speed-against-error table.
pub(super) struct Quality {
    pub(super) scene: String,
    pub(super) label: String,
    pub(super) ms: f64,
    pub(super) rmse: f64,
    pub(super) psnr: f64,
}

/// The worst setting's difference image against the reference.
pub(super) struct WorstDiff {
    pub(super) label: String,
    pub(super) rmse: f64,
    /// The PNG's file name beside the report, or why it was not written.
    pub(super) file: Result<String, String>,
}

/// Sampled primary rays of a frame checked against the f64 oracle.
pub(super) struct OracleCheck {
    pub(super) triangles: usize,
    pub(super) checked: usize,
    /// Hits beyond the rounding tolerance.
    pub(super) failed: usize,
    /// Hits on another triangle than the exact answer, within tolerance.
    pub(super) other_prim: usize,
}

/// Speed against error on one scene.
pub(super) struct QualityRun {
    pub(super) scene: String,
    pub(super) frame: u32,
    /// Seconds the reference took.
    pub(super) reference_s: f64,
    pub(super) rows: Vec<Quality>,
    pub(super) worst: Option<WorstDiff>,
    pub(super) oracle: OracleCheck,
}

/// One moving-object builder of a museum: medians per frame.
pub(super) struct BuilderRow {
    pub(super) label: &'static str,
    pub(super) commit_ms: f64,
    pub(super) render_ms: f64,
}

/// The builders of one museum's moving triangles, and the median per-frame
/// ratios of Whitted render time with refitted structures to structures
/// built afresh.
pub(super) struct BuilderRun {
    pub(super) scene: String,
    pub(super) rows: Vec<BuilderRow>,
    pub(super) kd_ratio: f64,
    pub(super) bvh_ratio: f64,
}

/// One museum's moving triangles rebuilt on the same frames by each builder.
pub(super) struct Rebuild {
    pub(super) scene: String,
    pub(super) triangles: usize,
    pub(super) fresh_ms: f64,
    pub(super) refit_ms: f64,
    pub(super) refits: usize,
    pub(super) frames: usize,
    pub(super) fresh_cost: f64,
    pub(super) refit_cost: f64,
    pub(super) embree_ms: Option<f64>,
    /// Embree refitting its own BVH of the triangles (`REFIT` quality).
    pub(super) embree_refit_ms: Option<f64>,
    /// The BVH: built afresh, refitted (`Bvh::refit`), refitted frames.
    pub(super) bvh_ms: f64,
    pub(super) bvh_refit_ms: f64,
    pub(super) bvh_refits: usize,
}

/// The same frames through an Embree two-level scene, single rays, one thread.
#[cfg_attr(not(feature = "embree"), allow(dead_code))]
pub(super) struct EmbreeRow {
    pub(super) scene: String,
    pub(super) ours_commit_ms: f64,
    pub(super) embree_update_ms: f64,
    pub(super) ours_mrays: f64,
    pub(super) embree_mrays: f64,
}

/// One frame of a scene split into its phases (one thread, timed).
pub(super) struct PhaseRow {
    pub(super) scene: String,
    pub(super) mode: &'static str,
    pub(super) backend: &'static str,
    /// Render time with the phase clocks on, and off (the same frame).
    pub(super) timed_ms: f64,
    pub(super) untimed_ms: f64,
    pub(super) phases: openrt_core::PhaseTimes,
    pub(super) pixels: u64,
}

impl PhaseRow {
    /// Nanoseconds per pixel outside the ray queries (camera rays, shading,
    /// the image, bookkeeping), from the timed frame.
    pub(super) fn outside_queries_ns_per_pixel(&self) -> f64 {
        (self.timed_ms * 1e6 - self.phases.queries_ns() as f64) / self.pixels.max(1) as f64
    }

    /// Surfaces, textures and the light loop as a share of the timed frame.
    pub(super) fn shading_share(&self) -> f64 {
        self.phases.shading_ns() as f64 / (self.timed_ms * 1e6).max(1.0)
    }
}

/// A skinned glTF figure played frame after frame: per frame medians of
/// its deformation and commit.
pub(super) struct DeformRow {
    pub(super) triangles: usize,
    pub(super) threads: usize,
    pub(super) accel: &'static str,
    /// Skinning the vertices on the pool.
    pub(super) skin_ms: f64,
    /// Redefining the object through the API (`Context::draw_elements`).
    pub(super) define_ms: f64,
    /// The object's build in the commit (a refit of the last frame's tree).
    pub(super) build_ms: f64,
    /// The rest of the commit (instance records, the top level).
    pub(super) other_commit_ms: f64,
    pub(super) refitted: usize,
    pub(super) frames: usize,
}

impl DeformRow {
    /// Skinning plus the refit: the per-frame figure.
    pub(super) fn skin_refit_ms(&self) -> f64 {
        self.skin_ms + self.build_ms
    }

    /// Everything a frame spends before rendering.
    pub(super) fn total_ms(&self) -> f64 {
        self.skin_ms + self.define_ms + self.build_ms + self.other_commit_ms
    }
}

/// Everything a run measured.
#[derive(Default)]
pub(super) struct Results {
    pub(super) frames: Vec<Row>,
    pub(super) phases: Vec<PhaseRow>,
    pub(super) diffs: Vec<ImageDiff>,
    pub(super) kinds: Vec<KindRow>,
    pub(super) quality: Vec<QualityRun>,
    pub(super) builders: Vec<BuilderRun>,
    /// Frames each builder rendered in the builders table.
    pub(super) builder_frames: usize,
    pub(super) rebuild_threads: usize,
    pub(super) rebuilds: Vec<Rebuild>,
    pub(super) embree: Vec<EmbreeRow>,
    pub(super) deforming: Vec<DeformRow>,
    /// The packet width of the run's renderers.
    pub(super) lanes: usize,
    /// The machine, as far as the standard library tells.
    pub(super) machine: String,
}
