//! What each fuzz target runs on one input. Plain Rust on raysift's public entry points, with
//! no libFuzzer in it: the fuzz targets (`fuzz_targets/*.rs`) call [`run`], and so does the
//! stable-toolchain test `crates/raysift/tests/fuzz_corpus.rs` (it includes this file), which
//! replays the committed corpus and regressions on every `cargo test --workspace`.
//!
//! An input passes when the reader returns `Ok`, or `Err` whose message starts with the input's
//! name (the project's `file: place: what`); a panic, an abort, a hang or an allocation past
//! libFuzzer's limits is a failure.

/// The fuzz targets, one per reader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// `scene::io::load_bytes` as `.obj`.
    Obj,
    /// `.ply` (ascii, binary little and big endian: the header chooses).
    Ply,
    /// `.off`.
    Off,
    /// `.gltf` / `.glb` (the `glTF` magic chooses), no file system.
    Gltf,
    /// `.gz`: the first byte picks the inner format, the rest is the gzip stream.
    Gzip,
    /// `rays::npy::parse_rays`, `parse_hits` and `parse_occlusion` on the same bytes.
    Npy,
}

impl Target {
    /// Every target, in the order of `fuzz/corpus/<name>`.
    pub const ALL: [Target; 6] = [
        Target::Obj,
        Target::Ply,
        Target::Off,
        Target::Gltf,
        Target::Gzip,
        Target::Npy,
    ];

    /// The target's name (its `fuzz/corpus/` and `fuzz/regressions/` folder, its binary).
    pub fn name(self) -> &'static str {
        match self {
            Target::Obj => "obj",
            Target::Ply => "ply",
            Target::Off => "off",
            Target::Gltf => "gltf",
            Target::Gzip => "gzip",
            Target::Npy => "npy",
        }
    }
}

/// The inner formats of the `gzip` target, chosen by the input's first byte.
const GZ_NAMES: [&str; 5] = [
    "fuzz.obj.gz",
    "fuzz.ply.gz",
    "fuzz.off.gz",
    "fuzz.gltf.gz",
    "fuzz.glb.gz",
];

fn check<T>(name: &str, r: raysift::Result<T>) {
    if let Err(e) = r {
        let msg = e.to_string();
        assert!(
            msg.starts_with(name),
            "error does not start with the input's name {name:?}: {msg}"
        );
    }
}

/// Runs `target` on `data`; panics only on a failure (see the module doc).
pub fn run(target: Target, data: &[u8]) {
    use raysift::scene::io::load_bytes;
    match target {
        Target::Obj => check("fuzz.obj", load_bytes(data, "fuzz.obj", None)),
        Target::Ply => check("fuzz.ply", load_bytes(data, "fuzz.ply", None)),
        Target::Off => check("fuzz.off", load_bytes(data, "fuzz.off", None)),
        Target::Gltf => {
            let name = if data.starts_with(b"glTF") {
                "fuzz.glb"
            } else {
                "fuzz.gltf"
            };
            check(name, load_bytes(data, name, None))
        }
        Target::Gzip => {
            let Some((&pick, rest)) = data.split_first() else {
                return;
            };
            let name = GZ_NAMES[pick as usize % GZ_NAMES.len()];
            check(name, load_bytes(rest, name, None))
        }
        Target::Npy => {
            use raysift::rays::npy;
            check("fuzz.npy", npy::parse_rays(data, "fuzz.npy"));
            check("fuzz.npy", npy::parse_hits(data, "fuzz.npy"));
            check("fuzz.npy", npy::parse_occlusion(data, "fuzz.npy"));
        }
    }
}
