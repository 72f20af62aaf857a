//! A small hand-built animated glTF for tests (library and CLI): a quad skinned to two joints
//! and a rigid triangle, with one animation `wave` of three channels:
//!
//! - node 0 (joint `root`, rest at the origin): translation, CUBICSPLINE, keys t = 0, 2:
//!   value (0,0,0) with out-tangent (1,0,0), then value (2,0,0) with in-tangent 0;
//! - node 1 (joint `tip`, child of `root`, rest translation (0,1,0)): rotation, LINEAR,
//!   keys t = 0, 2: identity, then 90° about +z;
//! - node 3 (rigid triangle (0,0,0) (1,0,0) (0,1,0), rest translation (5,0,0)): rotation, STEP,
//!   keys t = 0, 1: identity, then 90° about +z.
//!
//! Node 2 holds the quad (-0.5,0,0) (0.5,0,0) (0.5,2,0) (-0.5,2,0) with skin 0 (joints 0, 1;
//! inverse binds identity and translate(0,-1,0)) and a translation (100,0,0) that skinning
//! must ignore. The bottom vertices follow joint 0 alone; the top ones have raw weights 1 and 3
//! on joints 0 and 1 (normalised to 0.25 / 0.75). Scene mesh 0 is the quad, mesh 1 the triangle.

use serde_json::{json, Value};

/// Byte offsets in [`Rig::bin`] of each accessor's data.
pub mod at {
    /// Quad positions (4 × VEC3).
    pub const QUAD: usize = 0;
    /// Triangle positions (3 × VEC3).
    pub const TRI: usize = 48;
    /// Quad indices (6 × u16).
    pub const INDICES: usize = 84;
    /// JOINTS_0 (4 × VEC4 u16).
    pub const JOINTS: usize = 96;
    /// WEIGHTS_0 (4 × VEC4 f32).
    pub const WEIGHTS: usize = 128;
    /// Inverse bind matrices (2 × MAT4).
    pub const IBM: usize = 192;
    /// Times 0, 2 (LINEAR and CUBICSPLINE samplers).
    pub const TIMES: usize = 320;
    /// Times 0, 1 (STEP sampler).
    pub const TIMES_STEP: usize = 328;
    /// LINEAR rotation values (2 × VEC4).
    pub const ROT_LINEAR: usize = 336;
    /// STEP rotation values (2 × VEC4).
    pub const ROT_STEP: usize = 368;
    /// CUBICSPLINE translation values (6 × VEC3: in, value, out per key).
    pub const CUBIC: usize = 400;
    /// Total.
    pub const END: usize = 472;
}

/// The file as JSON plus its binary chunk; change either, then [`Rig::glb`].
pub struct Rig {
    /// The glTF JSON.
    pub json: Value,
    /// The BIN chunk.
    pub bin: Vec<u8>,
}

impl Default for Rig {
    fn default() -> Self {
        Self::new()
    }
}

impl Rig {
    /// The rig as described in the module doc.
    pub fn new() -> Self {
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let mut f: Vec<f32> = Vec::new();
        // Quad, triangle.
        f.extend([-0.5, 0.0, 0.0, 0.5, 0.0, 0.0, 0.5, 2.0, 0.0, -0.5, 2.0, 0.0]);
        f.extend([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
        let mut bin: Vec<u8> = f.iter().flat_map(|x| x.to_le_bytes()).collect();
        let u16s = |v: &[u16]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        bin.extend(u16s(&[0, 1, 2, 0, 2, 3]));
        bin.extend(u16s(&[0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0]));
        let mut g: Vec<f32> = Vec::new();
        g.extend([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
        g.extend([1.0, 3.0, 0.0, 0.0, 1.0, 3.0, 0.0, 0.0]);
        // Inverse binds, column-major: identity, translate(0, -1, 0).
        g.extend([1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.]);
        g.extend([1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., -1., 0., 1.]);
        g.extend([0.0, 2.0, 0.0, 1.0]);
        g.extend([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, h, h]);
        g.extend([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, h, h]);
        g.extend([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        g.extend([0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        bin.extend(g.iter().flat_map(|x| x.to_le_bytes()));
        assert_eq!(bin.len(), at::END);
        let spans = [
            (at::QUAD, 48),
            (at::TRI, 36),
            (at::INDICES, 12),
            (at::JOINTS, 32),
            (at::WEIGHTS, 64),
            (at::IBM, 128),
            (at::TIMES, 8),
            (at::TIMES_STEP, 8),
            (at::ROT_LINEAR, 32),
            (at::ROT_STEP, 32),
            (at::CUBIC, 72),
        ];
        let views: Vec<Value> = spans
            .iter()
            .map(|&(o, l)| json!({"buffer": 0, "byteOffset": o, "byteLength": l}))
            .collect();
        let acc = |view: usize, ty: &str, ct: u32, count: usize| {
            json!({"bufferView": view, "type": ty, "componentType": ct, "count": count})
        };
        let mut accessors = vec![
            acc(0, "VEC3", 5126, 4),
            acc(1, "VEC3", 5126, 3),
            acc(2, "SCALAR", 5123, 6),
            acc(3, "VEC4", 5123, 4),
            acc(4, "VEC4", 5126, 4),
            acc(5, "MAT4", 5126, 2),
            acc(6, "SCALAR", 5126, 2),
            acc(7, "SCALAR", 5126, 2),
            acc(8, "VEC4", 5126, 2),
            acc(9, "VEC4", 5126, 2),
            acc(10, "VEC3", 5126, 6),
        ];
        accessors[0]["min"] = json!([-0.5, 0.0, 0.0]);
        accessors[0]["max"] = json!([0.5, 2.0, 0.0]);
        accessors[1]["min"] = json!([0.0, 0.0, 0.0]);
        accessors[1]["max"] = json!([1.0, 1.0, 0.0]);
        accessors[6]["min"] = json!([0.0]);
        accessors[6]["max"] = json!([2.0]);
        accessors[7]["min"] = json!([0.0]);
        accessors[7]["max"] = json!([1.0]);
        let json = json!({
            "asset": {"version": "2.0"},
            "scene": 0,
            "scenes": [{"nodes": [0, 2, 3]}],
            "nodes": [
                {"name": "root", "children": [1]},
                {"name": "tip", "translation": [0.0, 1.0, 0.0]},
                {"name": "quad", "mesh": 0, "skin": 0, "translation": [100.0, 0.0, 0.0]},
                {"name": "tri", "mesh": 1, "translation": [5.0, 0.0, 0.0]}
            ],
            "meshes": [
                {"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 3, "WEIGHTS_0": 4}, "indices": 2}]},
                {"primitives": [{"attributes": {"POSITION": 1}}]}
            ],
            "skins": [{"joints": [0, 1], "inverseBindMatrices": 5}],
            "animations": [{
                "name": "wave",
                "channels": [
                    {"sampler": 0, "target": {"node": 0, "path": "translation"}},
                    {"sampler": 1, "target": {"node": 1, "path": "rotation"}},
                    {"sampler": 2, "target": {"node": 3, "path": "rotation"}}
                ],
                "samplers": [
                    {"input": 6, "output": 10, "interpolation": "CUBICSPLINE"},
                    {"input": 6, "output": 8, "interpolation": "LINEAR"},
                    {"input": 7, "output": 9, "interpolation": "STEP"}
                ]
            }],
            "buffers": [{"byteLength": at::END}],
            "bufferViews": views,
            "accessors": accessors
        });
        Self { json, bin }
    }

    /// Writes an f32 into the binary chunk at byte `offset`.
    pub fn set_f32(&mut self, offset: usize, v: f32) {
        self.bin[offset..offset + 4].copy_from_slice(&v.to_le_bytes());
    }

    /// The file as GLB bytes.
    pub fn glb(&self) -> Vec<u8> {
        let mut j = serde_json::to_vec(&self.json).expect("JSON");
        while j.len() % 4 != 0 {
            j.push(b' ');
        }
        let mut b = self.bin.clone();
        while b.len() % 4 != 0 {
            b.push(0);
        }
        let total = 12 + 8 + j.len() + 8 + b.len();
        let mut out = Vec::with_capacity(total);
        out.extend(b"glTF");
        out.extend(2u32.to_le_bytes());
        out.extend((total as u32).to_le_bytes());
        out.extend((j.len() as u32).to_le_bytes());
        out.extend(0x4E4F_534Au32.to_le_bytes());
        out.extend(j);
        out.extend((b.len() as u32).to_le_bytes());
        out.extend(0x004E_4942u32.to_le_bytes());
        out.extend(b);
        out
    }
}
