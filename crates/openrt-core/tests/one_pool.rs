//! One thread pool: the commit, the background SAH builds and the renderer
//! share it, and frames start no thread. Alone in its test binary, so that
//! no other test's threads come and go while it counts the process's.

use std::sync::Arc;

use glam::Vec3;
use openrt_accel::{Triangle, meshgen};
use openrt_core::{Camera, Context, Environment, PointLight, RenderMode, RenderSettings, Renderer};

mod common;
use common::define;

/// Threads of this process (Linux).
#[cfg(target_os = "linux")]
fn process_threads() -> usize {
    std::fs::read_to_string("/proc/self/status")
        .unwrap()
        .lines()
        .find_map(|l| l.strip_prefix("Threads:"))
        .and_then(|n| n.trim().parse().ok())
        .unwrap()
}

/// The thread count once it has stopped changing: the threads of a pool
/// that was dropped (the context's default one, replaced by `set_threads`)
/// exit in the background, after the drop returns.
#[cfg(target_os = "linux")]
fn settled_threads() -> usize {
    let mut last = process_threads();
    for _ in 0..500 {
        std::thread::sleep(std::time::Duration::from_millis(20));
        let now = process_threads();
        if now == last {
            return now;
        }
        last = now;
    }
    last
}

#[test]
fn one_pool_commits_renders_and_promotes_without_a_thread_per_frame() {
    let mut ctx = Context::new();
    // Promotions replace a kd-tree's fast build (a BVH has one builder).
    ctx.set_accel(openrt_core::Accel::Kd);
    let cam = Camera {
        from: Vec3::new(0.0, 0.5, 4.0),
        at: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 40.0,
        near: 0.0,
    };
    let env = Arc::new(Environment {
        lights: vec![PointLight {
            position: Vec3::new(3.0, 3.0, 3.0),
            color: Vec3::ONE,
        }],
        ambient: Vec3::splat(0.1),
        background: Vec3::new(0.1, 0.1, 0.2),
    });
    ctx.set_threads(2).unwrap();
    ctx.set_promote_after(Some(2));
    let pool = ctx.pool().unwrap();
    let shared = Renderer::with_pool(pool.clone());
    assert!(shared.pool().same(&pool) && shared.threads() == 2);
    let own = Renderer::new(1).unwrap();
    let settings = RenderSettings {
        width: 64,
        height: 48,
        mode: RenderMode::Whitted,
        max_depth: 3,
        ..RenderSettings::default()
    };
    let morphing = ctx.gen_object();
    define(&mut ctx, morphing, &meshgen::bumpy_sphere(3000, 3, 0.2));
    ctx.instantiate(morphing).unwrap();
    ctx.commit().unwrap();
    #[cfg(target_os = "linux")]
    let before = settled_threads();
    let mut promoted = false;
    for f in 0..12 {
        // Redefined for 4 frames, then left alone: a background SAH build
        // runs on the shared pool while frames render.
        if f < 4 {
            let tris: Vec<Triangle> = meshgen::bumpy_sphere(3000, 3, 0.2)
                .iter()
                .map(|t| t.map(|v| v * (1.0 + 0.01 * f as f32)))
                .collect();
            define(&mut ctx, morphing, &tris);
        }
        let s = ctx.commit().unwrap();
        promoted |= !s.promotions_started.is_empty();
        let a = shared.render(&ctx.scene(), &env, &cam, &settings).unwrap().0;
        let b = own.render(&ctx.scene(), &env, &cam, &settings).unwrap().0;
        assert_eq!(
            a.to_rgb8(),
            b.to_rgb8(),
            "frame {f}: the shared pool gives the same bytes"
        );
    }
    assert!(promoted, "a promotion ran on the shared pool");
    #[cfg(target_os = "linux")]
    assert_eq!(settled_threads(), before, "no thread was started for a frame");
}
