//! Minimal .npy reading and writing (little-endian, C order) for the formats the benchmark uses.

use std::io::{Read, Write};

pub struct Array {
    pub descr: String,
    pub shape: Vec<usize>,
    pub data: Vec<u8>,
}

fn field<'a>(header: &'a str, key: &str) -> Result<&'a str, String> {
    let k = format!("'{key}':");
    let at = header
        .find(&k)
        .ok_or_else(|| format!("npy header has no {key}: {header}"))?;
    Ok(header[at + k.len()..].trim_start())
}

pub fn read(path: &str) -> Result<Array, String> {
    let mut f = std::fs::File::open(path).map_err(|e| format!("{path}: {e}"))?;
    let mut bytes = Vec::new();
    f.read_to_end(&mut bytes).map_err(|e| format!("{path}: {e}"))?;
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(format!("{path}: not a .npy file"));
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(format!("{path}: unsupported .npy version {v}")),
    };
    let header = std::str::from_utf8(&bytes[start..start + hlen])
        .map_err(|_| format!("{path}: header is not text"))?
        .to_string();
    let d = field(&header, "descr")?;
    let descr = if d.starts_with('\'') {
        d[1..].split('\'').next().unwrap_or("").to_string()
    } else {
        return Err(format!("{path}: structured dtype not supported here: {header}"));
    };
    if field(&header, "fortran_order")?.starts_with("True") {
        return Err(format!("{path}: Fortran order not supported"));
    }
    let s = field(&header, "shape")?;
    let s = &s[1..s.find(')').ok_or("bad shape")?];
    let shape: Vec<usize> = s
        .split(',')
        .map(|x| x.trim())
        .filter(|x| !x.is_empty())
        .map(|x| x.parse::<usize>().map_err(|_| format!("{path}: bad shape {s}")))
        .collect::<Result<_, _>>()?;
    let data = bytes[start + hlen..].to_vec();
    Ok(Array { descr, shape, data })
}

impl Array {
    pub fn f32s(&self) -> Result<Vec<f32>, String> {
        if self.descr != "<f4" {
            return Err(format!("expected float32 '<f4', got {}", self.descr));
        }
        Ok(self
            .data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect())
    }

    /// Integer arrays of any common width, as u64 (negative values map to u64::MAX).
    pub fn indices(&self) -> Result<Vec<u64>, String> {
        let d = self.descr.trim_start_matches(['<', '|', '=']);
        let v = match d {
            "u4" => self.data.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().unwrap()) as u64).collect(),
            "i4" => self.data.chunks_exact(4).map(|c| {
                let x = i32::from_le_bytes(c.try_into().unwrap());
                if x < 0 { u64::MAX } else { x as u64 }
            }).collect(),
            "u8" => self.data.chunks_exact(8).map(|c| u64::from_le_bytes(c.try_into().unwrap())).collect(),
            "i8" => self.data.chunks_exact(8).map(|c| {
                let x = i64::from_le_bytes(c.try_into().unwrap());
                if x < 0 { u64::MAX } else { x as u64 }
            }).collect(),
            _ => return Err(format!("expected an integer array, got {}", self.descr)),
        };
        Ok(v)
    }
}

fn write_with_header(path: &str, dict: &str, payload: &[u8]) -> Result<(), String> {
    let mut header = dict.to_string();
    // magic(6) + version(2) + len(2) + header + '\n' padded to a multiple of 64.
    let total = 10 + header.len() + 1;
    let pad = (64 - total % 64) % 64;
    header.push_str(&" ".repeat(pad));
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len() + payload.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(payload);
    let mut f = std::fs::File::create(path).map_err(|e| format!("{path}: {e}"))?;
    f.write_all(&out).map_err(|e| format!("{path}: {e}"))
}

/// hits.npy: N records of t <f4, prim <u4, u <f4, v <f4.
pub fn write_hits(path: &str, t: &[f32], prim: &[u32], u: &[f32], v: &[f32]) -> Result<(), String> {
    let n = t.len();
    let dict = format!(
        "{{'descr': [('t', '<f4'), ('prim', '<u4'), ('u', '<f4'), ('v', '<f4')], 'fortran_order': False, 'shape': ({n},), }}"
    );
    let mut payload = Vec::with_capacity(16 * n);
    for i in 0..n {
        payload.extend_from_slice(&t[i].to_le_bytes());
        payload.extend_from_slice(&prim[i].to_le_bytes());
        payload.extend_from_slice(&u[i].to_le_bytes());
        payload.extend_from_slice(&v[i].to_le_bytes());
    }
    write_with_header(path, &dict, &payload)
}

/// Occlusion: uint8 array of N (1 = occluded).
pub fn write_u8(path: &str, x: &[u8]) -> Result<(), String> {
    let n = x.len();
    let dict = format!("{{'descr': '|u1', 'fortran_order': False, 'shape': ({n},), }}");
    write_with_header(path, &dict, x)
}
