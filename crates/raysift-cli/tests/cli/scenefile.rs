//! Scene description files, EXR output and `--quiet`: the repository's example scene renders,
//! flags override the file, and a bad file gives one line naming the file and the field, exit 2,
//! no image.

use super::*;

fn example() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/scenes/cornell.toml")
        .display()
        .to_string()
}

/// Reads a PNG's width and height from its IHDR chunk.
fn png_size(path: &str) -> (u32, u32) {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[1..4], b"PNG", "{path} is a PNG");
    let be = |i: usize| u32::from_be_bytes(b[i..i + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn example_scene_renders_and_flags_override_it() {
    let d = tmp();
    let out = p(d.path(), "c.png");
    let o = ok(&[
        "render",
        &example(),
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "1",
        "--out",
        &out,
        "--json",
        "--quiet",
    ]);
    let j = json(&o);
    assert_eq!(j["integrator"], "path", "the file's integrator");
    assert_eq!(j["bounces"], 5, "the file's bounces");
    assert_eq!(j["spp"], 1, "--spp overrides the file's 16");
    assert_eq!(j["tracer"], "bvh");
    assert_eq!(
        png_size(&out),
        (24, 16),
        "--width/--height override the file"
    );
    assert!(
        o.stderr.is_empty(),
        "--quiet and no terminal: nothing on stderr"
    );
    // Same seed, same image, whatever the thread count.
    let out2 = p(d.path(), "c2.png");
    ok(&[
        "render",
        &example(),
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "1",
        "--out",
        &out2,
        "--threads",
        "1",
        "--quiet",
    ]);
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&out2).unwrap());
}

#[test]
fn exr_holds_linear_radiance() {
    let d = tmp();
    let exr = p(d.path(), "c.exr");
    let png = p(d.path(), "c.png");
    let args = |out: &str| -> Vec<String> {
        [
            "render",
            "cornell",
            "--integrator",
            "path",
            "--spp",
            "1",
            "--bounces",
            "1",
            "--area-light",
            "0,1.9,0,0.5,20",
            "--width",
            "16",
            "--height",
            "16",
            "--out",
            out,
        ]
        .map(String::from)
        .to_vec()
    };
    let run = |out: &str| {
        let a = args(out);
        ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
    };
    run(&exr);
    run(&png);
    let b = std::fs::read(&exr).unwrap();
    assert_eq!(&b[..4], &[0x76, 0x2f, 0x31, 0x01], "OpenEXR magic number");
    // Float RGB for 256 pixels is at least 3 KiB before compression; the file holds floats,
    // not the 8-bit image.
    assert!(b.len() > 256, "{} bytes", b.len());
    // Ray casting makes no radiance: refused before any work.
    let out = p(d.path(), "r.exr");
    fails(&["render", "sphere:20", "--out", &out], "linear radiance");
    assert!(!Path::new(&out).exists());
    let out = p(d.path(), "r.tiff");
    fails(&["render", "sphere:20", "--out", &out], ".exr");
}

/// Writes `text` as `name` in `dir` and renders it; it must fail naming the file and `needle`,
/// writing no image.
fn bad_scene(dir: &Path, name: &str, text: &str, needle: &str) {
    let f = p(dir, name);
    std::fs::write(&f, text).unwrap();
    let out = p(dir, "never.png");
    let e = fails(
        &["render", &f, "--out", &out, "--width", "8", "--height", "8"],
        needle,
    );
    assert!(e.contains(&f), "the error names the file: {e}");
    assert!(!Path::new(&out).exists(), "{name}: no image written");
}

#[test]
fn bad_scene_files_fail_naming_file_and_field() {
    let d = tmp();
    let dir = d.path();
    let bunny = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/bunny.ply.gz")
        .display()
        .to_string();
    bad_scene(
        dir,
        "unknown.toml",
        "[camera]\nzoom = 2\n",
        "unknown field `zoom`",
    );
    bad_scene(
        dir,
        "unknown-top.toml",
        "[[meshes]]\ngenerator = \"cornell\"\n[sky]\n",
        "unknown field `sky`",
    );
    bad_scene(
        dir,
        "unknown.json",
        r#"{"meshes": [{"generator": "cornell", "colour": 1}]}"#,
        "unknown field `colour`",
    );
    bad_scene(dir, "syntax.toml", "[camera\n", "line 1");
    bad_scene(
        dir,
        "missing.toml",
        "[[meshes]]\npath = \"nowhere.obj\"\n",
        "meshes[0].path",
    );
    bad_scene(dir, "none.toml", "[camera]\nfov = 40\n", "meshes");
    bad_scene(
        dir,
        "both.toml",
        &format!("[[meshes]]\ngenerator = \"cornell\"\npath = {bunny:?}\n"),
        "meshes[0]: give exactly one of path and generator",
    );
    bad_scene(
        dir,
        "zero-light.toml",
        "[[meshes]]\ngenerator = \"cornell\"\n[[lights]]\ncentre = [0, 1.9, 0]\nsize = 0\npower = 10\n",
        "lights[0]: size 0 gives a light of zero area",
    );
    bad_scene(
        dir,
        "negative-light.toml",
        "[[meshes]]\ngenerator = \"cornell\"\n[[lights]]\ncentre = [0, 1.9, 0]\nsize = 1\npower = -10\n",
        "lights[0]: power -10 must be finite and non-negative",
    );
    bad_scene(
        dir,
        "negative-emission.toml",
        "[[meshes]]\ngenerator = \"cornell\"\nmaterial = { emission = [-1, 0, 0] }\n",
        "meshes[0].material: emission",
    );
    bad_scene(
        dir,
        "integrator.toml",
        "[[meshes]]\ngenerator = \"cornell\"\n[render]\nintegrator = \"photon\"\n",
        "render.integrator",
    );
    bad_scene(
        dir,
        "spp.toml",
        "[[meshes]]\ngenerator = \"cornell\"\n[render]\nintegrator = \"path\"\nspp = 0\n",
        "render.spp",
    );
    // A flat mesh (all its triangles of zero area) as a light or a mirror.
    let flat = p(dir, "flat.obj");
    std::fs::write(&flat, "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n").unwrap();
    bad_scene(
        dir,
        "flat-light.toml",
        "[[meshes]]\ngenerator = \"cornell\"\n[[meshes]]\npath = \"flat.obj\"\nmaterial = { emission = [5, 5, 5] }\n",
        "meshes[1].material.emission: the mesh has zero area",
    );
    bad_scene(
        dir,
        "flat-mirror.toml",
        "[[meshes]]\ngenerator = \"cornell\"\n[[meshes]]\npath = \"flat.obj\"\nmaterial = { mirror = true }\n",
        "meshes[1].material.mirror: the mesh has no surface of non-zero area",
    );
    // Squashed to nothing by its transform.
    bad_scene(
        dir,
        "scale.toml",
        "[[meshes]]\ngenerator = \"cornell\"\nscale = [1, 0, 1]\n",
        "meshes[0].scale",
    );
}
