//! Every limit of the scene formats: the bad input gives an error that
//! names the file (and the line where there is one) and the limit.

use std::path::{Path, PathBuf};

use openrt_scene::{
    MAX_ANIMART_TRIANGLES, MAX_BLOCK_NESTING, MAX_FILE_BYTES, MAX_FRAMES, MAX_HEADER_COUNT, MAX_INCLUDES,
    MAX_SCENE_TRIANGLES, MAX_SPHERE_SEGMENTS, MAX_TERRAIN_GRID, MAX_TEXTURE_SIDE, MAX_TREE_TRIANGLES, MAX_TREES,
    ScenePlayer, load_ron_any,
};

fn write(dir: &Path, name: &str, text: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Opens `path` and returns the error text; the open must fail.
fn error_of(path: &Path) -> String {
    match ScenePlayer::open(Some(path)) {
        Ok(_) => panic!("{} opened, but it breaks a limit", path.display()),
        Err(e) => e.to_string(),
    }
}

fn assert_names(e: &str, parts: &[&str]) {
    for p in parts {
        assert!(e.contains(p), "'{e}' should contain '{p}'");
    }
}

const VIEW: &str = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0.1\nresolution 32 32\n";

#[test]
fn aff_block_nesting() {
    let dir = tempfile::tempdir().unwrap();
    let nest = |n: usize| {
        format!(
            "{VIEW}{}p 3 0 0 0 1 0 0 0 1 0\n{}",
            "xs 1 1 1 0 0 1 0 0 0 0 {\n".repeat(n),
            "}\n".repeat(n)
        )
    };
    let ok = write(dir.path(), "ok.aff", nest(MAX_BLOCK_NESTING));
    ScenePlayer::open(Some(&ok)).unwrap();
    let deep = write(dir.path(), "deep.aff", nest(MAX_BLOCK_NESTING + 1));
    let e = error_of(&deep);
    assert_names(
        &e,
        &["deep.aff:", &format!("{MAX_BLOCK_NESTING} levels (MAX_BLOCK_NESTING)")],
    );
    // Animated nodes count too, and 200,000 levels neither overflow the
    // stack nor take long.
    let nodes = format!("{VIEW}{}", "x n {\n".repeat(200_000));
    let e = error_of(&write(dir.path(), "nodes.aff", nodes));
    assert_names(&e, &["nodes.aff:", "MAX_BLOCK_NESTING"]);
}

#[test]
fn aff_header_counts_and_reservations() {
    let dir = tempfile::tempdir().unwrap();
    let over = MAX_HEADER_COUNT + 1;
    for (name, text) in [
        ("m.aff", format!("{VIEW}m vertices {over}")),
        ("p.aff", format!("{VIEW}p {over} 0 0 0")),
        ("k.aff", format!("{VIEW}k name {{ transl {over}")),
        ("big.aff", format!("{VIEW}m vertices 99999999999999999999999")),
    ] {
        let e = error_of(&write(dir.path(), name, text));
        assert_names(&e, &[name]);
    }
    // Counts at the limit with almost no data: an error at the end of the
    // file, without reserving for 50 million items first.
    for (name, text) in [
        ("m2.aff", format!("{VIEW}m vertices {MAX_HEADER_COUNT} 1 2 3")),
        ("p2.aff", format!("{VIEW}p {MAX_HEADER_COUNT} 0 0 0")),
        ("k2.aff", format!("{VIEW}k name {{ rot {MAX_HEADER_COUNT} 0")),
        ("t2.aff", format!("{VIEW}tpa {MAX_HEADER_COUNT} 0")),
    ] {
        // NOTE: no clock: the loader reserving for the header's count
        // first would show as an allocation failure or an abort here.
        let e = error_of(&write(dir.path(), name, text));
        assert_names(&e, &[name, "file ends"]);
    }
}

#[test]
fn aff_include_count_and_depth() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "empty.aff", "# nothing\n");
    let ok = write(
        dir.path(),
        "ok.aff",
        format!(
            "{VIEW}p 3 0 0 0 1 0 0 0 1 0\n{}",
            "i 0 empty.aff\n".repeat(MAX_INCLUDES - 1)
        ),
    );
    ScenePlayer::open(Some(&ok)).unwrap();
    let many = write(
        dir.path(),
        "many.aff",
        format!("{VIEW}{}", "i 0 empty.aff\n".repeat(MAX_INCLUDES + 1)),
    );
    assert_names(&error_of(&many), &["many.aff:", "(MAX_INCLUDES)"]);
    // A file including itself twice multiplies: stopped by the depth limit.
    let bomb = write(dir.path(), "bomb.aff", "i 0 bomb.aff\ni 0 bomb.aff\n");
    assert_names(&error_of(&bomb), &["bomb.aff", "MAX_INCLUDE_DEPTH"]);
}

#[test]
fn scene_resolution_is_checked_in_both_formats() {
    let dir = tempfile::tempdir().unwrap();
    let aff = write(
        dir.path(),
        "r.aff",
        VIEW.replace("resolution 32 32", "resolution 16384 16384"),
    );
    assert_names(&error_of(&aff), &["r.aff:7:", "image pixel count", "33554432"]);
    let aff0 = write(dir.path(), "r0.aff", VIEW.replace("resolution 32 32", "resolution 0 5"));
    assert_names(&error_of(&aff0), &["r0.aff:7:"]);
    for (name, res) in [
        ("a.ron", "(4294967295, 4294967295)"),
        ("b.ron", "(0, 10)"),
        ("c.ron", "(16385, 1)"),
    ] {
        let ron = write(dir.path(), name, format!("(version: 1, resolution: {res})"));
        assert_names(&error_of(&ron), &[name, "resolution:"]);
    }
}

fn ron_error(dir: &Path, name: &str, body: &str) -> String {
    let p = write(dir, name, format!("(version: 2, {body})"));
    match load_ron_any(&p) {
        Ok(_) => panic!("{name} loaded"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn ron_generator_sphere_and_frame_limits() {
    let dir = tempfile::tempdir().unwrap();
    let terrain = |grid: u32, trees: u32, tree_triangles: u32| {
        format!(
            "generators: [Terrain(size: 10.0, grid: {grid}, height: 1.0, trees: {trees}, tree_triangles: {tree_triangles}, tree_size: 1.0, sway_degrees: 0.0, seed: 1)]"
        )
    };
    let e = ron_error(dir.path(), "g.ron", &terrain(MAX_TERRAIN_GRID + 1, 0, 10));
    assert_names(
        &e,
        &[
            "g.ron",
            &format!(
                "grid {} is beyond the limit of {MAX_TERRAIN_GRID}",
                MAX_TERRAIN_GRID + 1
            ),
        ],
    );
    let e = ron_error(dir.path(), "t.ron", &terrain(4, MAX_TREES + 1, 10));
    assert_names(&e, &["t.ron", "trees"]);
    let e = ron_error(dir.path(), "tt.ron", &terrain(4, 1, MAX_TREE_TRIANGLES + 1));
    assert_names(&e, &["tt.ron", "tree_triangles"]);
    // Each within its limit, together beyond the scene's triangle limit.
    let e = ron_error(dir.path(), "all.ron", &terrain(MAX_TERRAIN_GRID, 1, MAX_TREE_TRIANGLES));
    assert!(2 * (MAX_TERRAIN_GRID as usize).pow(2) > MAX_SCENE_TRIANGLES);
    assert_names(&e, &["all.ron", "(MAX_SCENE_TRIANGLES)"]);
    let e = ron_error(
        dir.path(),
        "nan.ron",
        &terrain(4, 1, 10).replace("size: 10.0", "size: inf"),
    );
    assert_names(&e, &["nan.ron", "Terrain"]);
    let sphere = |segments: u32| {
        format!("objects: {{ \"s\": Sphere(center: (0.0, 0.0, 0.0), radius: 1.0, segments: {segments}) }}")
    };
    let e = ron_error(dir.path(), "s.ron", &sphere(MAX_SPHERE_SEGMENTS + 1));
    assert_names(&e, &["s.ron", "(MAX_SPHERE_SEGMENTS)"]);
    assert_names(&ron_error(dir.path(), "s0.ron", &sphere(0)), &["s0.ron", "segments 0"]);
    let e = ron_error(
        dir.path(),
        "f.ron",
        &format!("animation: Some((start: 0.0, end: 1.0, frames: {}))", MAX_FRAMES + 1),
    );
    assert_names(&e, &["f.ron", "(MAX_FRAMES)"]);
    let e = ron_error(
        dir.path(),
        "art.ron",
        &format!(
            "bart: Some((file: \"museum/museum5.aff\", animart_triangles: Some({})))",
            MAX_ANIMART_TRIANGLES + 1
        ),
    );
    assert_names(&e, &["art.ron", "(MAX_ANIMART_TRIANGLES)"]);
}

#[test]
fn ron_keys_follow_the_aff_rules() {
    let dir = tempfile::tempdir().unwrap();
    let base = "objects: { \"b\": Box(min: (0.0, 0.0, 0.0), max: (1.0, 1.0, 1.0)) }, ";
    for (name, keys, expect) in [
        (
            "dec.ron",
            "translate: [(1.0, (0.0, 0.0, 0.0)), (0.5, (1.0, 0.0, 0.0))]",
            "must not decrease (0.5 after 1)",
        ),
        ("nan.ron", "translate: [(NaN, (0.0, 0.0, 0.0))]", "not finite"),
        ("inf.ron", "scale: [(0.0, (inf, 1.0, 1.0))]", "not finite"),
        ("axis.ron", "rotate: [(0.0, (0.0, 0.0, 0.0), 30.0)]", "not zero"),
        (
            "rdec.ron",
            "rotate: [(2.0, (0.0, 1.0, 0.0), 30.0), (1.0, (0.0, 1.0, 0.0), 30.0)]",
            "must not decrease",
        ),
    ] {
        let e = ron_error(
            dir.path(),
            name,
            &format!("{base}instances: [(object: \"b\", keys: Some(({keys})))]"),
        );
        assert_names(&e, &[name, "instance 0 (b)", expect]);
    }
    let e = ron_error(
        dir.path(),
        "cam.ron",
        "camera_keys: Some((from: [(0.0, (0.0, 0.0, 5.0)), (-1.0, (0.0, 0.0, 4.0))]))",
    );
    assert_names(&e, &["cam.ron", "camera 'from' keys", "must not decrease"]);
    let e = ron_error(
        dir.path(),
        "morph.ron",
        "objects: { \"m\": Morph(triangles: [(0, 1, 2)], keys: [(NaN, [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)])]) }",
    );
    assert_names(&e, &["morph.ron", "object 'm'", "not finite"]);
}

#[test]
fn ron_nesting_is_bounded_by_the_parser() {
    let dir = tempfile::tempdir().unwrap();
    let deep = format!("(version: 1, lights: {}{})", "[".repeat(100_000), "]".repeat(100_000));
    let e = ron_error(dir.path(), "deep.ron", &deep[13..deep.len() - 1]);
    assert_names(&e, &["deep.ron:1:"]);
}

#[test]
fn oversized_files_and_textures() {
    let dir = tempfile::tempdir().unwrap();
    // A sparse file just over the size limit: refused before it is read.
    let big = dir.path().join("big.aff");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(MAX_FILE_BYTES + 1)
        .unwrap();
    assert_names(&error_of(&big), &["big.aff", "(MAX_FILE_BYTES)"]);
    let start = std::time::Instant::now();
    for (name, header) in [
        ("wide.ppm", format!("P6 {} 1 255\n", MAX_TEXTURE_SIDE + 1)),
        ("huge.ppm", "P6 100000 100000 255\n".to_string()),
    ] {
        write(dir.path(), name, header.as_bytes());
        let scene = write(
            dir.path(),
            &format!("{name}.aff"),
            format!("{VIEW}tt {name} 0 0 0 0 0 1 0 0 1 0 0 1 0 1 0\n"),
        );
        assert_names(&error_of(&scene), &[name, "texture limits"]);
    }
    assert!(
        start.elapsed().as_secs() < 2,
        "refused without decoding: {:?}",
        start.elapsed()
    );
}
