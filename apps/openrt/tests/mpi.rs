//! Distributed rendering under `mpirun -n 3` (feature `mpi`): the images
//! equal the single-process images byte for byte, and a failing or silent
//! worker makes rank 0 report it by rank within a bounded time.
//!
//! Run: `cargo test -p openrt --features mpi --test mpi` (needs Open MPI's
//! `mpirun`; `scripts/setup.sh` installs it).
#![cfg(feature = "mpi")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../scenes/{name}.ron"))
}

/// `openrt args`, alone (`ranks` = 1) or under `mpirun -n ranks`.
fn openrt(ranks: u32, args: &[&str], env: &[(&str, &str)]) -> (Output, Duration) {
    let mut cmd = if ranks == 1 {
        Command::new(env!("CARGO_BIN_EXE_openrt"))
    } else {
        let mut c = Command::new("timeout");
        c.args(["120", "mpirun", "-n", &ranks.to_string(), "--oversubscribe"])
            .arg(env!("CARGO_BIN_EXE_openrt"));
        c
    };
    cmd.args(args)
        // Open MPI refuses root without these (CI runs as root).
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
    for (k, v) in env {
        cmd.env(k, v);
    }
    let start = Instant::now();
    let out = cmd.output().expect("openrt (or mpirun) runs");
    (out, start.elapsed())
}

fn have_mpirun() -> bool {
    let ok = Command::new("mpirun").arg("--version").output().is_ok();
    assert!(
        ok || std::env::var_os("CI").is_none(),
        "mpirun not found (scripts/setup.sh installs Open MPI)"
    );
    ok
}

#[test]
fn three_ranks_render_the_single_process_bytes() {
    if !have_mpirun() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (name, mode) in [("textured", "whitted"), ("animated", "gl"), ("room", "whitted")] {
        let mut images = Vec::new();
        for (ranks, flag) in [
            (1, "--strict"),
            (3, "--strict"),
            (3, "--mpi-root-renders"),
            (3, "--mpi-tiles=static"),
        ] {
            let png = dir.path().join(format!("{name}-{ranks}-{flag}.png"));
            let (out, _) = openrt(
                ranks,
                &[
                    flag,
                    "render",
                    scene(name).to_str().unwrap(),
                    "--width",
                    "97",
                    "--height",
                    "61",
                    "--threads",
                    "1",
                    "--mode",
                    mode,
                    "--frame",
                    "0",
                    "-o",
                    png.to_str().unwrap(),
                ],
                &[],
            );
            assert!(
                out.status.success(),
                "{name}, {ranks} ranks: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            if ranks == 3 {
                assert!(
                    String::from_utf8_lossy(&out.stdout).contains("\"ranks\":3"),
                    "rendered distributed"
                );
            }
            images.push(std::fs::read(&png).unwrap());
        }
        assert!(images[0] == images[1], "{name} {mode}: 3 ranks give other bytes");
        assert!(
            images[0] == images[2],
            "{name} {mode}: 3 ranks with rank 0 rendering give other bytes"
        );
    }
}

#[test]
fn played_frames_match_and_only_changes_are_sent() {
    if !have_mpirun() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let play = |ranks: u32, out: &Path| {
        let (o, _) = openrt(
            ranks,
            &[
                "play",
                scene("animated").to_str().unwrap(),
                "--frames",
                "0..6",
                "--width",
                "64",
                "--height",
                "48",
                "--threads",
                "1",
                "-o",
                out.to_str().unwrap(),
            ],
            &[],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    let (one, three) = (dir.path().join("one"), dir.path().join("three"));
    play(1, &one);
    play(3, &three);
    for f in 0..6 {
        let name = format!("frame_{f:05}.png");
        assert!(
            std::fs::read(one.join(&name)).unwrap() == std::fs::read(three.join(&name)).unwrap(),
            "frame {f} differs"
        );
    }
    let stats = std::fs::read_to_string(three.join("stats.jsonl")).unwrap();
    let sent: Vec<u64> = stats
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).unwrap()["distributed"]["bytes_sent"]
                .as_u64()
                .unwrap()
        })
        .collect();
    // The first frame sends the scene; later ones the morph's vertices and
    // the moved instances only.
    assert!(sent[0] > 2 * sent[1], "{sent:?}");
    assert!(sent[1..].iter().all(|&b| b == sent[1]), "{sent:?}");
}

#[test]
fn a_failing_or_silent_worker_is_reported_by_rank() {
    if !have_mpirun() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("f.png");
    let room = scene("room");
    let args = [
        "render",
        room.to_str().unwrap(),
        "--width",
        "32",
        "--height",
        "24",
        "--threads",
        "1",
        "-o",
        png.to_str().unwrap(),
    ];
    let (out, took) = openrt(3, &args, &[("OPENRT_MPI_FAULT", "fail:2")]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("MPI rank 2: injected build failure"), "{err}");
    assert!(took < Duration::from_mins(1), "{took:?}");
    let (out, took) = openrt(
        3,
        &args,
        &[("OPENRT_MPI_FAULT", "hang:1"), ("OPENRT_MPI_TIMEOUT_S", "3")],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("MPI rank 1 stopped answering"), "{err}");
    assert!(took < Duration::from_mins(1), "bounded: {took:?}");
    // A worker process that exits: Open MPI's runtime ends the job (rank 0
    // included: without ULFM no process survives a dead rank, and
    // `--enable-recovery` keeps MPI_Abort from ending the job), with the
    // worker's exit code and its rank named, within seconds.
    let (out, took) = openrt(3, &args, &[("OPENRT_MPI_FAULT", "exit:2")]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(
        err.contains("exited with non-zero status") && err.contains(",2]"),
        "{err}"
    );
    assert!(took < Duration::from_secs(30), "bounded: {took:?}");
}
