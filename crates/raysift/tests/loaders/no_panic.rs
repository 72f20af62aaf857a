//! Truncated and byte-flipped versions of the valid test files must give `Ok` or `Err`,
//! never a panic (proptest reports a panic as a failure).

#[allow(unused_imports)]
use super::{gltf::*, obj::*, off::*, ply::*};
use proptest::prelude::*;
use raysift::scene::io::{gltf, obj, off, ply};

fn samples() -> Vec<(&'static str, Vec<u8>)> {
    let buf = gltf_buffer();
    vec![
        ("a.obj", b"v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvn 0 0 1\ng x\nf 1/1/1 2/1/1 3/1/1\nf -3 -2 -1\nl 1 2\n".to_vec()),
        ("a.ply", ply_ascii().into_bytes()),
        ("le.ply", ply_binary(false)),
        ("be.ply", ply_binary(true)),
        ("a.off", b"OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n3 3 2 1\n".to_vec()),
        (
            "a.gltf",
            gltf_json(&format!(
                r#"{{"byteLength": 60, "uri": "data:application/octet-stream;base64,{}"}}"#,
                base64(&buf)
            ))
            .into_bytes(),
        ),
        ("a.glb", glb(&gltf_json(r#"{"byteLength": 60}"#), &buf)),
    ]
}

fn parse(name: &str, bytes: &[u8]) {
    let _ = match name.rsplit('.').next().unwrap() {
        "obj" => obj::parse(bytes, name),
        "ply" => ply::parse(bytes, name),
        "off" => off::parse(bytes, name),
        _ => gltf::parse(bytes, name, None),
    };
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]
    #[test]
    fn mangled_files_never_panic(
        which in 0usize..7,
        cut in 0.0f64..1.0,
        flips in proptest::collection::vec((0.0f64..1.0, any::<u8>()), 0..4),
    ) {
        let (name, mut bytes) = samples().swap_remove(which);
        for (at, b) in flips {
            let n = bytes.len();
            bytes[(((n as f64) * at) as usize).min(n - 1)] = b;
        }
        // About a sixth of the cases keep the whole file.
        let keep = ((bytes.len() as f64) * (1.2 * cut)).min(bytes.len() as f64) as usize;
        parse(name, &bytes[..keep]);
    }
}
