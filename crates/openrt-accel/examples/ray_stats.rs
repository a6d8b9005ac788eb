//! Where a ray's time goes: counts the work per ray (box entry, interior
//! nodes, empty and non-empty leaves, references and leaf blocks) for the
//! camera and random rays of the kdtree bench, and times the rays that
//! enter the mesh box apart from those that miss it.
//! `cargo run --release -p openrt-accel --example ray_stats -- [N]`
use glam::Vec3;
use openrt_accel::{Aabb, KdTree, Ray, meshgen, traverse};

/// Interior nodes and empty leaves whose cells the segment `[t0, t1]` of
/// `r` pierces (a plain walk without the traversal's error margins).
fn cells(tree: &KdTree, r: &Ray, t0: f32, t1: f32) -> (usize, usize) {
    let (mut inner, mut empty) = (0, 0);
    let mut stack = vec![(Some(0u32), t0, t1)];
    while let Some((i, a, b)) = stack.pop() {
        // An empty cell has no node (`KdNode::children`).
        let Some(i) = i else {
            empty += 1;
            continue;
        };
        let nd = tree.nodes()[i as usize];
        if nd.is_leaf() {
            continue;
        }
        inner += 1;
        let (o, d, split) = (r.origin[nd.axis()], r.dir[nd.axis()], nd.split());
        let ts = (split - o) / d;
        let below_first = o < split || (o == split && d < 0.0);
        let [below, above] = nd.children(i);
        let (near, far) = if below_first { (below, above) } else { (above, below) };
        if ts.is_nan() || ts <= 0.0 || ts >= b {
            stack.push((near, a, b));
        } else if ts <= a {
            stack.push((far, a, b));
        } else {
            stack.push((far, ts, b));
            stack.push((near, a, ts));
        }
    }
    (inner, empty)
}

fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let tris = meshgen::bumpy_sphere(n, 42, 0.5);
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    let tree = KdTree::build_sah(tris).unwrap();
    let cam = meshgen::camera_rays(Vec3::new(0.5, 0.8, -3.5), Vec3::ZERO, 256, 256, 50.0);
    let rnd = meshgen::random_rays(65_536, 7, b);
    for (name, rays) in [("camera", &cam), ("random", &rnd)] {
        let (inside, outside): (Vec<&Ray>, Vec<&Ray>) = rays.iter().partition(|r| tree.bounds().clip(r).is_some());
        let (mut inner, mut empty, mut leaves, mut refs, mut blocks, mut hits) =
            (0usize, 0usize, 0usize, 0usize, 0usize, 0usize);
        for r in &inside {
            let Some((t0, t1)) = tree.bounds().clip(r) else {
                continue;
            };
            let hit = tree.intersect(r);
            hits += usize::from(hit.is_some());
            let mut closest = hit.map_or(t1, |h| h.t);
            let (i, e) = cells(&tree, r, t0, closest);
            (inner, empty) = (inner + i, empty + e);
            traverse(tree.nodes(), r, t0, t1, &mut closest, |leaf, _| {
                leaves += 1;
                refs += leaf.prim_count() as usize;
                blocks += (leaf.prim_count() as usize).div_ceil(4);
                false
            });
        }
        let ns = |set: &[&Ray]| {
            (0..9)
                .map(|_| {
                    let t = std::time::Instant::now();
                    std::hint::black_box(set.iter().filter(|r| tree.intersect(r).is_some()).count());
                    t.elapsed().as_secs_f64() * 1e9 / set.len().max(1) as f64
                })
                .fold(f64::INFINITY, f64::min)
        };
        let k = inside.len().max(1) as f64;
        println!(
            "{name}: {:.2} of rays enter the box; per entering ray: hit {:.2}, {:.1} interior nodes, {:.2} empty \
             leaves, {:.2} leaves, {:.1} references in {:.1} blocks, {:.0} ns (best of 9); {:.1} ns per ray \
             missing the box",
            inside.len() as f64 / rays.len() as f64,
            hits as f64 / k,
            inner as f64 / k,
            empty as f64 / k,
            leaves as f64 / k,
            refs as f64 / k,
            blocks as f64 / k,
            ns(&inside),
            ns(&outside)
        );
    }
}
