//! The report of `openrt bench` (docs/BENCHMARKS.md), rendered from a run's
//! typed results: every table, and the verdict of every goal (`goals.rs`).

use std::fmt::Write as _;

use openrt_core::{Accel, Backend, TOP_LEVEL_BVH_MIN};

use super::BenchOptions;
use super::goals;
use super::goals::{
    CLOSE_DB, PACKETS_VS_SINGLE, PAPER, REFERENCE_SPP, TRILINEAR_ERROR_RATIO, TRILINEAR_TIME_RATIO, targets, verdict,
};
use super::results::{QualityRun, Results, Row};

/// The whole report; `plot` is the speed-against-error plot's file name or
/// why it was not written, `secs` the run's duration.
pub(super) fn render(o: &BenchOptions, res: &Results, plot: &Result<String, String>, secs: f64) -> String {
    let mut md = String::new();
    frame_tables(&mut md, o, res);
    kind_table(&mut md, res);
    top_level_table(&mut md, res);
    phase_table(&mut md, res);
    // The tables below use the default backend.
    let rows: Vec<&Row> = res.frames.iter().filter(|r| r.backend == default_label()).collect();
    paper_tables(&mut md, &rows);
    target_list(&mut md, res);
    let _ = writeln!(md, "\n## Speed against error (middle frame, {}x{})", o.width, o.height);
    for q in &res.quality {
        quality_section(&mut md, q);
    }
    builder_sections(&mut md, res);
    rebuild_table(&mut md, res);
    deform_table(&mut md, res);
    embree_table(&mut md, res);
    match plot {
        Ok(file) => {
            let _ = writeln!(md, "\n![frame time against error]({file})");
        }
        Err(e) => {
            let _ = writeln!(md, "\n(plot not written: {e})");
        }
    }
    let _ = writeln!(md, "\nThe whole run took {secs:.0} s.");
    md
}

/// The report of a `--device` run (docs/BENCHMARKS-DEVICE.md): the frame
/// rates, the paper's table and the thread scaling of each backend measured.
pub(super) fn render_device(o: &BenchOptions, res: &Results, secs: f64) -> String {
    let mut md = String::new();
    frame_tables(&mut md, o, res);
    let of = |b: &str| -> Vec<&Row> { res.frames.iter().filter(|r| r.backend == b).collect() };
    paper_by_cpus(&mut md, &of(default_label()));
    paper_tables(&mut md, &of(default_label()));
    for b in [Backend::Packets.label(Accel::Kd), "embree-packet"] {
        scaling_table(&mut md, &of(b), b);
    }
    let _ = writeln!(
        md,
        "\nOnly what depends on the thread count is measured here; the one-thread sections (ray queries, phases, builders, speed against error) are in BENCHMARKS.md.\n\nThe whole run took {secs:.0} s."
    );
    md
}

/// The paper's frame rates against this run's at the same number of CPUs
/// (its clients had 2 CPUs each; one thread here is one CPU).
fn paper_by_cpus(md: &mut String, rows: &[&Row]) {
    let _ = writeln!(
        md,
        "\n## The paper's table at equal CPU counts (fps, paper / here with `{}`)\n\nThe paper's clients had 2 CPUs each (its 1, 2, 4, 8, 16 clients are 2, 4, 8, 16, 32 CPUs); here one thread is one core.\n\n| scene | mode | 2 CPUs | 4 | 8 | 16 | 32 (paper only) |\n|---|---|---:|---:|---:|---:|---:|",
        default_label()
    );
    for (scene, mode, p) in PAPER {
        let at = |t: usize| {
            rows.iter()
                .find(|r| r.scene == *scene && r.mode == *mode && r.threads == t)
                .map_or("-".to_string(), |r| format!("{:.2}", r.fps()))
        };
        let paper = |v: f64| if v.is_nan() { "-".to_string() } else { format!("{v}") };
        let cells: Vec<String> = [2, 4, 8, 16]
            .iter()
            .zip(p)
            .map(|(&t, &v)| format!("{} / {}", paper(v), at(t)))
            .collect();
        let _ = writeln!(md, "| {scene} | {mode} | {} | {} |", cells.join(" | "), paper(p[4]));
    }
}

/// The header, the frame-rate table, the backends side by side and the images.
fn frame_tables(md: &mut String, o: &BenchOptions, res: &Results) {
    let rows = &res.frames;
    let _ = writeln!(
        md,
        "# Benchmarks{}\n\nGenerated {} by `{}` ({}) on {} ({}); {}x{}, Whitted depth 3, medians over {} frames sampled across each animation. Frame time = commit (top-level rebuild, fast rebuilds or refits, promotions) + render, each sampled frame committed right after the two frames before it (untimed), as when the animation plays, so that a refit starts from the last frame's tree; fps = 1000 / frame time.\n",
        if o.device { " on the 16-core machine" } else { "" },
        humantime::format_rfc3339_seconds(std::time::SystemTime::now()),
        o.command,
        if cfg!(feature = "embree") {
            "a build with `--features embree`"
        } else {
            "a build without Embree"
        },
        res.machine,
        std::env::consts::ARCH,
        o.width,
        o.height,
        o.frames
    );
    let _ = writeln!(
        md,
        "## Frame rates on this machine\n\n| scene | mode | backend | threads | fps | commit ms | top-level ms | moving objects ms | promotions | render ms | rays/frame | instances | triangles |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.2} | {:.2} | {:.3} | {:.2} | {} | {:.1} | {:.0} | {} | {} |",
            r.scene,
            r.mode,
            r.backend,
            r.threads,
            r.fps(),
            r.commit_ms,
            r.toplevel_ms,
            r.fast_ms,
            r.promotions,
            r.render_ms,
            r.rays,
            r.instances,
            r.triangles
        );
    }
    let _ = writeln!(
        md,
        "\n## Ray packets against single rays, and against Embree\n\nThe same frames through every backend of this build: `kd` (this crate's packets of {} lanes on this CPU over kd-trees), `kd-single` (its single rays), and with `--features embree` Embree 3 one ray at a time (`embree`: rtcIntersect1/rtcOccluded1) and in packets of the same width (`embree-packet`: rtcIntersect4/8/16, rtcOccluded4/8/16; a packet of 32 lanes as two of 16, Embree's widest), one Embree scene per object (HIGH quality, LOW for redefined objects) under a top-level scene committed every frame, its build counted in its render time. The kd images are the same bytes (tested in `crates/openrt-scene/tests/backends.rs`); Embree's differ only by its own hits. fps = 1000 / (commit + render). `bvh` and `bvh-single`: the same packets and single rays with BVHs under the instances (the default structure, `--accel bvh`: packets walk 4-wide nodes, single rays an 8-wide copy on AVX2 CPUs), the same bytes. The kd-trees and the BVHs have a player each; the two play the sampled frames in turn, frame by frame (which goes first changing from frame to frame), so that the machine's slow phases fall on both alike; the Targets judge the default structure by these rows.\n\n| scene | mode | threads | kd fps | kd-single fps | kd / kd-single | embree fps | embree-packet fps | kd / embree-packet | goal kd >= embree-packet | bvh fps | bvh-single fps | bvh / kd | bvh / embree-packet | goal bvh >= embree-packet |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---|",
        res.lanes
    );
    let find = |r: &Row, b: &str| {
        rows.iter()
            .find(|q| q.backend == b && q.scene == r.scene && q.mode == r.mode && q.threads == r.threads)
            .map(Row::fps)
    };
    for r in rows.iter().filter(|r| r.backend == Backend::Packets.label(Accel::Kd)) {
        let f = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.2}"));
        let ratio = |v: Option<f64>| v.map_or("-".into(), |v| format!("{:.2}x", r.fps() / v));
        let (single, em, emp) = (find(r, "kd-single"), find(r, "embree"), find(r, "embree-packet"));
        let goal = |fps: Option<f64>| match (fps, emp) {
            (Some(f), Some(e)) if f >= e => "met",
            (Some(_), Some(_)) => "**not met**",
            (None, _) => "not measured",
            (_, None) => "not measured (build without Embree)",
        };
        let verdict = goal(Some(r.fps()));
        let (bvh, bvh_single) = (find(r, "bvh"), find(r, "bvh-single"));
        let bvh_ratio = match (bvh, emp) {
            (Some(b), Some(e)) => format!("{:.2}x", b / e),
            _ => "-".into(),
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {} | {} | {} | {} | {} | {verdict} | {} | {} | {} | {bvh_ratio} | {} |",
            r.scene,
            r.mode,
            r.threads,
            r.fps(),
            f(single),
            ratio(single),
            f(em),
            f(emp),
            ratio(emp),
            f(bvh),
            f(bvh_single),
            bvh.map_or("-".into(), |b| format!("{:.2}x", b / r.fps())),
            goal(bvh),
        );
    }
    let _ = writeln!(
        md,
        "\nImages against the `kd` image of the same frame (first sampled frame of each scene):\n\n| scene | mode | backend | same bytes | pixels off by more than 8/255 |\n|---|---|---|---|---:|"
    );
    for d in &res.diffs {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.3}% |",
            d.scene,
            d.mode,
            d.backend,
            if d.identical { "yes" } else { "no" },
            100.0 * d.off_share
        );
    }
}

/// Ray queries alone, per scene and kind.
fn kind_table(md: &mut String, res: &Results) {
    if res.kinds.is_empty() {
        return;
    }
    let lanes = res.lanes;
    let _ = writeln!(
        md,
        "\nRay queries alone, per scene (middle frame, one thread, no shading; medians of 5 passes): primary rays in the renderer's pixel blocks ({lanes} lanes), closest hit; the shadow rays from their hits to each light, any hit (the kd and BVH backends try each light's last occluder first, as in a frame; Embree's any-hit query names no occluder). `bvh-single` and `bvh`: the same queries with BVHs under the instances (`--accel bvh`: 8-wide single rays on AVX2 CPUs, 4-wide packets); goal: `bvh` >= `embree-packet`.\n\n| scene | rays | count | kd-single Mrays/s | kd Mrays/s | kd / kd-single | goal {PACKETS_VS_SINGLE}x | embree Mrays/s | embree-packet Mrays/s | kd / embree-packet | bvh-single Mrays/s | bvh Mrays/s | bvh / embree-packet | goal bvh >= embree-packet |\n|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---|"
    );
    for k in &res.kinds {
        let ratio = k.packet / k.single;
        let met = verdict(ratio >= PACKETS_VS_SINGLE);
        let (em, emp, vs) = k.embree.map_or(("-".into(), "-".into(), "-".into()), |(a, b)| {
            (format!("{a:.2}"), format!("{b:.2}"), format!("{:.2}x", k.packet / b))
        });
        let (bs, bp) = k.bvh;
        let (bvs, bgoal) = k
            .embree
            .map_or(("-".into(), "not measured (build without Embree)"), |(_, b)| {
                (format!("{:.2}x", bp / b), verdict(bp >= b))
            });
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.2} | {ratio:.2}x | {met} | {em} | {emp} | {vs} | {bs:.2} | {bp:.2} | {bvs} | {bgoal} |",
            k.scene, k.kind, k.rays, k.single, k.packet
        );
    }
}

/// The query table's kd rows under each top level.
fn top_level_table(md: &mut String, res: &Results) {
    if res.kinds.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\nThe top level over the instances (the same queries, kd-trees under the instances): the paper's BSP (Algorithm 1) against a four-wide BVH over the instance boxes (`--top-level bsp|bvh`; `auto`, the default, takes the BVH from {TOP_LEVEL_BVH_MIN} instances). The same answers, bit for bit.\n\n| scene | rays | instances | default | kd-single BSP Mrays/s | kd-single BVH Mrays/s | BVH / BSP | kd BSP Mrays/s | kd BVH Mrays/s | BVH / BSP |\n|---|---|---:|---|---:|---:|---:|---:|---:|---:|"
    );
    for k in &res.kinds {
        let [sb, sv, pb, pv] = k.top;
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {sb:.2} | {sv:.2} | {:.2}x | {pb:.2} | {pv:.2} | {:.2}x |",
            k.scene,
            k.kind,
            k.top_default.1,
            k.top_default.0,
            sv / sb,
            pv / pb
        );
    }
}

/// Each scene's middle frame split into phases.
fn phase_table(md: &mut String, res: &Results) {
    if res.phases.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Where a frame's time goes\n\nThe middle frame of each scene on one thread, split by the renderer's phase clocks (`Renderer::set_phase_timing`; `openrt render --phases` prints the same split): ms per phase, the median of three timed frames, taken in three rounds in which every backend renders once. Shadow rays include their set-up, the light loop the bounce rays' set-up; \"other\" is the tile loop, the bounces' pooling and the clocks themselves (the timed frame against the untimed one, same bytes, in the second column). Outside queries: everything but the primary, shadow and bounce queries, per pixel. Shading: surfaces, textures and light loop.\n\n| scene | mode | backend | frame ms (timed / untimed) | camera | primary | shadow | bounce | surface | textures | light loop | image | other | outside queries ns/pixel | shading share |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for r in &res.phases {
        let p = &r.phases;
        let ms = |ns: u64| ns as f64 / 1e6;
        let other = r.timed_ms - ms(p.total_ns());
        let spans: Vec<String> = p.named().iter().map(|&(_, ns)| format!("{:.1}", ms(ns))).collect();
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.1} / {:.1} | {} | {:.1} | {:.0} | {:.0}% |",
            r.scene,
            r.mode,
            r.backend,
            r.timed_ms,
            r.untimed_ms,
            spans.join(" | "),
            other,
            r.outside_queries_ns_per_pixel(),
            100.0 * r.shading_share()
        );
    }
}

/// The paper's table beside this run's, and thread scaling.
fn paper_tables(md: &mut String, rows: &[&Row]) {
    let _ = writeln!(
        md,
        "\n## Beside the paper (Wald, Benthin & Slusallek 2003)\n\nThe paper's columns count rendering clients of 2 CPUs each: its \"1\" is 2 CPUs and its \"16\" is 32. Per CPU, its single client gave half its frame rate; compare that with one thread here.\n\n| scene | mode | paper, 1 client (2 CPUs) | 2 (4) | 4 (8) | 8 (16) | 16 (32) | paper per CPU | here, 1 thread | here, max threads | scaling |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for (scene, mode, p) in PAPER {
        let here: Vec<&Row> = rows
            .iter()
            .copied()
            .filter(|r| r.scene == *scene && r.mode == *mode)
            .collect();
        let one = here.iter().find(|r| r.threads == 1).map(|r| r.fps());
        let max = here.iter().max_by_key(|r| r.threads).map(|r| (r.threads, r.fps()));
        let f = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.2}"));
        let scaling = match (one, max) {
            (Some(a), Some((t, b))) if t > 1 => format!("{:.2}x on {t}", b / a),
            _ => "-".into(),
        };
        let paper = |v: f64| if v.is_nan() { "-".to_string() } else { format!("{v}") };
        let _ = writeln!(
            md,
            "| {scene} | {mode} | {} | {} | {} | {} | {} | {:.3} | {} | {} | {scaling} |",
            paper(p[0]),
            paper(p[1]),
            paper(p[2]),
            paper(p[3]),
            paper(p[4]),
            p[0] / 2.0,
            f(one),
            f(max.map(|m| m.1))
        );
    }
    scaling_table(md, rows, default_label());
}

/// Thread scaling of `backend`'s `rows`: every measured thread count,
/// beside the paper's 1..16 CPUs (only where more than two were measured).
fn scaling_table(md: &mut String, rows: &[&Row], backend: &str) {
    let counts: Vec<usize> = {
        let mut c: Vec<usize> = rows.iter().map(|r| r.threads).collect();
        c.sort_unstable();
        c.dedup();
        c
    };
    if counts.len() > 2 {
        let heads: Vec<String> = counts.iter().map(|t| format!("{t} thr")).collect();
        let _ = writeln!(
            md,
            "\n## Thread scaling, `{backend}` (fps; speedup and parallel efficiency against 1 thread)\n\n| scene | mode | {} | speedup | efficiency | paper speedup 1 -> 16 clients (2 -> 32 CPUs) |\n|---|---|{}---:|---:|---:|",
            heads.join(" | "),
            "---:|".repeat(counts.len())
        );
        let mut pairs: Vec<(&str, &str)> = Vec::new();
        for r in rows {
            if !pairs.contains(&(r.scene.as_str(), r.mode)) {
                pairs.push((r.scene.as_str(), r.mode));
            }
        }
        for (scene, mode) in pairs {
            let at = |t: usize| {
                rows.iter()
                    .find(|r| r.scene == scene && r.mode == mode && r.threads == t)
                    .map(|r| r.fps())
            };
            let cells: Vec<String> = counts
                .iter()
                .map(|&t| at(t).map_or("-".into(), |v| format!("{v:.2}")))
                .collect();
            let max = *counts.last().unwrap_or(&1);
            let (speedup, eff) = match (at(1), at(max)) {
                (Some(a), Some(b)) if a > 0.0 => {
                    (format!("{:.2}x", b / a), format!("{:.0}%", 100.0 * b / a / max as f64))
                }
                _ => ("-".into(), "-".into()),
            };
            let paper = PAPER
                .iter()
                .find(|(s, m, _)| *s == scene && *m == mode)
                .map_or("-".into(), |(_, _, p)| format!("{:.2}x", p[4] / p[0]));
            let _ = writeln!(
                md,
                "| {scene} | {mode} | {} | {speedup} | {eff} | {paper} |",
                cells.join(" | ")
            );
        }
    }
}

/// The default backend's rows: packets over the default object structure.
fn default_label() -> &'static str {
    Backend::Packets.label(Accel::default())
}

/// Every goal's verdict.
fn target_list(md: &mut String, res: &Results) {
    let _ = writeln!(md, "\n## Targets (this machine)\n");
    for t in targets(res, default_label()) {
        let _ = writeln!(md, "{}", t.line());
    }
    // Packets against single rays, per ray kind over the scenes.
    for kind in ["primary", "shadow"] {
        let of_kind: Vec<(&String, f64)> = res
            .kinds
            .iter()
            .filter(|k| k.kind == kind)
            .map(|k| (&k.scene, k.packet / k.single))
            .collect();
        if of_kind.is_empty() {
            continue;
        }
        let met: Vec<&str> = of_kind
            .iter()
            .filter(|(_, r)| *r >= PACKETS_VS_SINGLE)
            .map(|(n, _)| n.as_str())
            .collect();
        let lo = of_kind.iter().map(|(_, r)| *r).fold(f64::INFINITY, f64::min);
        let hi = of_kind.iter().map(|(_, r)| *r).fold(0.0, f64::max);
        let verdict = if met.len() == of_kind.len() {
            "met on every scene".to_string()
        } else if met.is_empty() {
            "**not met** on any scene".to_string()
        } else {
            format!(
                "**not met** on {} of {} scenes (met on {})",
                of_kind.len() - met.len(),
                of_kind.len(),
                met.join(", ")
            )
        };
        let _ = writeln!(
            md,
            "- {kind} rays in packets against single rays (ray queries table): {lo:.2}-{hi:.2}x over {} scenes (goal {PACKETS_VS_SINGLE} x): {verdict}",
            of_kind.len()
        );
    }
    let _ = writeln!(
        md,
        "- ray throughput against Embree: single mesh in docs/PERFORMANCE.md (`cargo bench -p openrt-accel --bench kdtree --features embree`, which measures it); two-level scenes in the side-by-side table below."
    );
}

/// Speed against error on one scene.
fn quality_section(md: &mut String, run: &QualityRun) {
    let (name, f, reference_s, q) = (&run.scene, run.frame, run.reference_s, &run.rows);
    let _ = writeln!(
        md,
        "\n### {name} (frame {f})\n\nReference: Whitted depth 8, {REFERENCE_SPP} samples per pixel, trilinear textures ({reference_s:.0} s to render). Every row differs from the default (Whitted depth 3, 1 sample per pixel, trilinear) in one setting; lower resolutions are upsampled (nearest) before comparison.\n\n| setting | render ms | RMSE | PSNR dB |\n|---|---:|---:|---:|"
    );
    for x in q {
        let _ = writeln!(md, "| {} | {:.1} | {:.4} | {:.1} |", x.label, x.ms, x.rmse, x.psnr);
    }
    let cheapest = q
        .iter()
        .filter(|x| x.psnr >= CLOSE_DB)
        .min_by(|a, b| a.ms.total_cmp(&b.ms));
    if let Some(c) = cheapest {
        let _ = writeln!(
            md,
            "\nThe cheapest setting within {CLOSE_DB} dB of the reference: **{}** ({:.1} ms, {:.1} dB).",
            c.label, c.ms, c.psnr
        );
    } else {
        let best = q.iter().max_by(|a, b| a.psnr.total_cmp(&b.psnr));
        let _ = writeln!(
            md,
            "\nNo setting is within {CLOSE_DB} dB of the reference; the closest is {}.",
            best.map_or("-".into(), |b| format!(
                "{} ({:.1} dB, {:.1} ms)",
                b.label, b.psnr, b.ms
            ))
        );
    }
    let row = |l: &str| q.iter().find(|x| x.label.starts_with(l));
    if let (Some(tri), Some(bi)) = (row("Whitted depth 3 (trilinear"), row("depth 3, bilinear")) {
        let (e, c) = (tri.rmse / bi.rmse, tri.ms / bi.ms);
        let goal = if name == "robots" {
            format!(
                " (goal for the robots: error at most x{TRILINEAR_ERROR_RATIO} for at most x{TRILINEAR_TIME_RATIO}: {})",
                verdict(e <= TRILINEAR_ERROR_RATIO && c <= TRILINEAR_TIME_RATIO)
            )
        } else {
            String::new()
        };
        let _ = writeln!(
            md,
            "Trilinear against bilinear at 1 sample: error x{e:.2}, frame time x{c:.2}{goal}."
        );
    }
    if let Some(w) = &run.worst {
        match &w.file {
            Ok(file) => {
                let _ = writeln!(
                    md,
                    "\nThe worst row, {} (RMSE {:.4}), against the reference, differences x4:\n\n![{name}: worst row against the reference]({file})",
                    w.label, w.rmse
                );
            }
            Err(e) => {
                let _ = writeln!(md, "\n(difference image not written: {e})");
            }
        }
    }
    let o = &run.oracle;
    let _ = writeln!(
        md,
        "\nNumerical error of the accelerated path on {name} (frame {f}): {} sampled primary rays checked against the brute-force f64 oracle over {} world-space triangles: **{} disagree beyond rounding tolerance ({:.3}%)**; {} ({:.2}%) report a different first triangle than the exact f64 answer, all within the tolerance (shared edges, coplanar overlaps, grazing hits).",
        o.checked,
        o.triangles,
        o.failed,
        100.0 * o.failed as f64 / o.checked.max(1) as f64,
        o.other_prim,
        100.0 * o.other_prim as f64 / o.checked.max(1) as f64
    );
}

/// Fast (refitted or afresh), SAH and BVH structures for the museums' moving triangles.
fn builder_sections(md: &mut String, res: &Results) {
    if res.builders.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Moving objects: fast, refitted and SAH trees\n\nThe museums' moving triangles under each builder (`Context::set_refit`, `Context::set_redefinition_builder`; the BVH rows with `Context::set_accel`), each sampled frame committed right after the two frames before it, as when the animation plays; same triangles, so the cost moves between commit and render. The builders take turns frame by frame (the first of them changing from frame to frame), so that the machine's phases fall on all of them alike; medians over {} frames.",
        res.builder_frames
    );
    for b in &res.builders {
        let _ = writeln!(
            md,
            "\n### {}\n\n| moving-object builder | commit ms (median) | Whitted render ms | frame ms |\n|---|---:|---:|---:|",
            b.scene
        );
        for r in &b.rows {
            let _ = writeln!(
                md,
                "| {} | {:.2} | {:.1} | {:.1} |",
                r.label,
                r.commit_ms,
                r.render_ms,
                r.commit_ms + r.render_ms
            );
        }
    }
}

/// The museums' moving triangles rebuilt by each builder, against Embree LOW.
fn rebuild_table(md: &mut String, res: &Results) {
    if res.rebuilds.is_empty() {
        return;
    }
    let threads = res.rebuild_threads;
    let _ = writeln!(
        md,
        "\n## Rebuilding the moving triangles ({threads} threads)\n\nEvery other frame of each museum's animation, in order; per frame the moving triangles (handed over as a commit hands them: moved, so their copy is not timed; Embree copies them into its own buffer, timed, on one device made before the first frame with the same threads), each build run where a commit runs it (on the {threads}-thread pool from {} triangles up, below that on the calling thread: `BspBuilder::install_build`), are built afresh by the fast builder, refitted on the last frame's tree (`KdTree::refit_fast`: the old split planes with the new triangles, leaves that overflow split further, rebuilt afresh when the SAH cost exceeds {:.2}x the last full build's; what a commit does by default), and{} built by Embree at LOW quality and refitted by Embree (`REFIT` quality: its scene made on the first frame, then its vertex buffer rewritten and the scene committed); medians. SAH cost: expected steps and tests per ray (`KdTree::sah_cost`), mean over the frames. The BVH columns: the same triangles built afresh (`Bvh::build`) and refitted on the last frame's BVH (`Bvh::refit`, rebuilt past {:.2}x the last build's SAH cost); goal: BVH refit <= Embree LOW and Embree REFIT.\n\n| scene | triangles | fast afresh ms | refit ms | refitted frames | Embree LOW ms | Embree LOW / refit | Embree REFIT ms | SAH cost afresh | SAH cost refit | BVH afresh ms | BVH refit ms | BVH refitted frames | Embree LOW / BVH refit | Embree REFIT / BVH refit | goal |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
        openrt_accel::PARALLEL_MIN,
        openrt_accel::DEFAULT_REFIT_COST_LIMIT,
        if cfg!(feature = "embree") {
            ""
        } else {
            " (with `--features embree`)"
        },
        openrt_accel::BVH_REFIT_COST_LIMIT
    );
    for r in &res.rebuilds {
        let (e, ratio) = match r.embree_ms {
            Some(e) => (format!("{e:.3}"), format!("{:.2}", e / r.refit_ms.max(1e-9))),
            None => ("-".into(), "-".into()),
        };
        let of_bvh = |x: Option<f64>| x.map_or("-".into(), |x| format!("{:.2}", x / r.bvh_refit_ms.max(1e-9)));
        let (bvh_ratio, refit_ratio) = (of_bvh(r.embree_ms), of_bvh(r.embree_refit_ms));
        let er = r.embree_refit_ms.map_or("-".into(), |x| format!("{x:.3}"));
        let goal = match (r.embree_ms, r.embree_refit_ms) {
            (Some(e), Some(f)) => verdict(r.bvh_refit_ms <= e.min(f)),
            _ => "not measured (build without Embree)",
        };
        let _ = writeln!(
            md,
            "| {} | {} | {:.3} | {:.3} | {} / {} | {e} | {ratio} | {er} | {:.2} | {:.2} | {:.3} | {:.3} | {} / {} | {bvh_ratio} | {refit_ratio} | {goal} |",
            r.scene,
            r.triangles,
            r.fresh_ms,
            r.refit_ms,
            r.refits,
            r.frames,
            r.fresh_cost,
            r.refit_cost,
            r.bvh_ms,
            r.bvh_refit_ms,
            r.bvh_refits,
            r.frames
        );
    }
}

/// Skinned glTF figures played: what a deforming mesh costs per frame.
fn deform_table(md: &mut String, res: &Results) {
    if res.deforming.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Deforming glTF meshes\n\nThe skinned figure of `scenes/walker.glb` (`openrt_scene::skinned_figure_glb`: a tube on 8 joints, each vertex weighted between two) at each size, played for {} frames after the first; per frame medians: skinning the vertices on the pool (`GltfPlayer::deform_times`), redefining the object through the API (`Context::draw_elements`, one call per primitive, with the API's checks and the triangles' validity test), its build in the commit (a refit of the last frame's tree unless the refit's SAH cost check rebuilds it; `refitted` counts the frames whose build was a refit), and the rest of the commit (instance records, the top level). Goal: skinning + refit of 100k triangles <= {} ms on the most threads.\n\n| triangles | threads | structure | skinning ms | redefinition ms | build (refit) ms | rest of commit ms | refitted | skinning + refit ms | whole frame before rendering ms |\n|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|",
        super::measure::DEFORM_FRAMES,
        goals::SKIN_REFIT_100K_MS
    );
    for r in &res.deforming {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {} / {} | {:.2} | {:.2} |",
            r.triangles,
            r.threads,
            r.accel,
            r.skin_ms,
            r.define_ms,
            r.build_ms,
            r.other_commit_ms,
            r.refitted,
            r.frames,
            r.skin_refit_ms(),
            r.total_ms()
        );
    }
}

/// The same frames through an Embree two-level scene (builds with `--features embree`).
fn embree_table(md: &mut String, res: &Results) {
    if !cfg!(feature = "embree") {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Side by side with Embree 3 (two-level, single rays, 1 thread)\n\nSame frames, same primary rays; Embree: one scene per object (HIGH quality, LOW for objects rebuilt every frame) instanced in a top-level scene updated per frame.\n\n| scene | OpenRT-rs commit ms | Embree update ms | commit ratio (Embree/ours) | OpenRT-rs Mrays/s | Embree Mrays/s | throughput ratio (ours/Embree) |\n|---|---:|---:|---:|---:|---:|---:|"
    );
    for e in &res.embree {
        let _ = writeln!(
            md,
            "| {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
            e.scene,
            e.ours_commit_ms,
            e.embree_update_ms,
            e.embree_update_ms / e.ours_commit_ms.max(1e-9),
            e.ours_mrays,
            e.embree_mrays,
            e.ours_mrays / e.embree_mrays
        );
    }
}

#[cfg(test)]
mod tests {
    use super::super::BenchOptions;
    use super::super::results::{Results, Row};
    use super::render_device;

    fn row(backend: &'static str, threads: usize, render_ms: f64) -> Row {
        Row {
            triangles: 110_520,
            instances: 6,
            ..Row::sample("kitchen", backend, threads, render_ms)
        }
    }

    #[test]
    fn the_device_report_sets_the_paper_beside_equal_cpu_counts() {
        let frames = [1, 2, 4, 8, 16]
            .into_iter()
            .flat_map(|t| {
                // bvh (the default): perfect scaling from 2 s at one thread; kd at half that rate.
                let ms = 2000.0 / t as f64;
                [row("bvh", t, ms), row("kd", t, 2.0 * ms)]
            })
            .collect();
        let res = Results {
            frames,
            lanes: 16,
            machine: "test machine, 16 cores".into(),
            ..Results::default()
        };
        let o = BenchOptions {
            scenes: vec!["kitchen".into()],
            frames: 3,
            width: 640,
            height: 480,
            threads: vec![1, 2, 4, 8, 16],
            deform_sizes: Vec::new(),
            out: "BENCHMARKS-DEVICE.md".into(),
            command: "openrt bench --device".into(),
            device: true,
        };
        let md = render_device(&o, &res, 1.0);
        assert!(md.starts_with("# Benchmarks on the 16-core machine"), "{md}");
        // The paper's 1, 2, 4, 8 clients (2..16 CPUs) beside 2..16 threads.
        assert!(
            md.contains("| kitchen | Whitted | 0.25 / 1.00 | 0.5 / 2.00 | 1.05 / 4.00 | 2 / 8.00 | 4 |"),
            "{md}"
        );
        // Scaling of each backend measured, none of the one-thread sections.
        assert!(md.contains("## Thread scaling, `kd`") && md.contains("## Thread scaling, `bvh`"));
        assert!(
            md.contains("| 0.50 | 1.00 | 2.00 | 4.00 | 8.00 | 16.00x | 100% |"),
            "{md}"
        );
        assert!(!md.contains("Speed against error") && !md.contains("## Targets"));
    }
}
