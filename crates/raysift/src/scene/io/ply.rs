//! PLY loader: `ascii 1.0`, `binary_little_endian 1.0` and `binary_big_endian 1.0`.
//!
//! Reads the `vertex` element's `x`, `y`, `z` (any scalar type, any position among other
//! properties) and the `face` element's `vertex_indices` (or `vertex_index`) list (any count
//! and index types); polygons are fanned in order, `(v0, v1, v2), (v0, v2, v3), ...`. All other
//! elements and properties are parsed past and ignored. The result is one mesh named after the
//! file.
//!
//! Why a focused reader rather than `ply-rs`: the maintained fork `ply-rs-bw` 4.0.1 is robust
//! on the malformed inputs tried (no panics) but took 2.37 s in release on this project's
//! 871K-triangle Stanford dragon (2.2 s of it parsing into per-element hash maps), before any
//! conversion; this reader streams straight into `Vec3`/`[u32; 3]` and reports errors with the
//! line (ascii) or byte offset (binary) the project's error convention asks for.
//!
//! Strictness: element counts must match the data exactly (a missing element, a short line, an
//! extra value on a line or data after the last element is an error), coordinates must be
//! finite and indices in range. Faces with fewer than 3 vertices produce no triangle. An
//! element without properties holds no data (no bytes, no line), whatever its count.
//!
//! Limits: before any data is read, each element's count times its smallest possible size (in
//! binary the sum of its scalar sizes and list count sizes; in ascii two characters per
//! property, a digit and a separator) must fit in the bytes after the header, so a header
//! claiming 10^12 vertices in a 200-byte file fails at once, naming the element.

use crate::error::{Error, Result};
use crate::scene::Mesh;
use glam::Vec3;

/// PLY scalar types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn parse(s: &str) -> Option<Ty> {
        Some(match s {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Ty::F32 | Ty::F64)
    }
}

#[derive(Clone, Debug)]
enum Prop {
    Scalar(Ty),
    /// A list: count type, item type.
    List(Ty, Ty),
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<(String, Prop)>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Le,
    Be,
}

/// What to pull out of an element.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Vertex { xyz: [usize; 3] },
    Face { list: usize },
    Other,
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the first data byte.
    body: usize,
    /// Line number of the first body line (ascii).
    body_line: usize,
}

/// Parses PLY bytes into one mesh.
pub fn parse(bytes: &[u8], file: &str) -> Result<Vec<Mesh>> {
    let err = |place: String, msg: String| Error::parse(file, place, msg);
    if bytes.is_empty() {
        return Err(err("line 1".into(), "empty file".into()));
    }
    let header = parse_header(bytes, file)?;
    let kinds = classify(&header.elements, file)?;
    check_counts(&header, bytes.len() - header.body, file)?;
    let vertex_count = header
        .elements
        .iter()
        .zip(&kinds)
        .find(|(_, k)| matches!(k, Kind::Vertex { .. }))
        .map(|(e, _)| e.count)
        .unwrap_or(0);
    if vertex_count > u32::MAX as usize {
        return Err(err(
            "header".into(),
            format!(
                "{vertex_count} vertices; at most {} are supported",
                u32::MAX
            ),
        ));
    }
    let mut out = Out {
        positions: Vec::new(),
        indices: Vec::new(),
        vertex_count: vertex_count as u32,
    };
    match header.encoding {
        Encoding::Ascii => read_ascii(bytes, &header, &kinds, file, &mut out)?,
        Encoding::Le => read_binary::<false>(bytes, &header, &kinds, file, &mut out)?,
        Encoding::Be => read_binary::<true>(bytes, &header, &kinds, file, &mut out)?,
    }
    let name = std::path::Path::new(file)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| file.to_string());
    Ok(vec![Mesh::new(name, out.positions, out.indices)])
}

struct Out {
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    vertex_count: u32,
}

fn parse_header(bytes: &[u8], file: &str) -> Result<Header> {
    let err = |line: usize, msg: String| Error::parse(file, format!("line {line}"), msg);
    let mut pos = 0;
    let mut line_no = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line_no += 1;
        if pos >= bytes.len() {
            return Err(err(
                line_no,
                "unexpected end of file in the header (no end_header)".into(),
            ));
        }
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|i| pos + i);
        let (raw, next) = match end {
            Some(e) => (&bytes[pos..e], e + 1),
            None => (&bytes[pos..], bytes.len()),
        };
        // The header is short; refuse absurd "lines" so binary junk fails fast and clearly.
        if raw.len() > 4096 {
            return Err(err(line_no, "header line longer than 4096 bytes".into()));
        }
        let text = std::str::from_utf8(raw)
            .map_err(|_| err(line_no, "header is not valid text".into()))?;
        let text = text.strip_suffix('\r').unwrap_or(text);
        pos = next;
        let mut words = text.split_ascii_whitespace();
        let first = words.next();
        if line_no == 1 {
            if text.trim() != "ply" {
                return Err(err(
                    1,
                    format!("not a PLY file (expected \"ply\", found {:?})", short(text)),
                ));
            }
            continue;
        }
        match first {
            None => continue,
            Some("comment") | Some("obj_info") => continue,
            Some("format") => {
                let enc = match words.next() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::Le,
                    Some("binary_big_endian") => Encoding::Be,
                    other => {
                        return Err(err(line_no, format!("unknown PLY format {other:?}")));
                    }
                };
                match words.next() {
                    Some("1.0") | Some("1") => {}
                    v => return Err(err(line_no, format!("unsupported PLY version {v:?}"))),
                }
                encoding = Some(enc);
            }
            Some("element") => {
                let (Some(name), Some(count), None) = (words.next(), words.next(), words.next())
                else {
                    return Err(err(line_no, "expected \"element NAME COUNT\"".into()));
                };
                let count: usize = count
                    .parse()
                    .map_err(|_| err(line_no, format!("bad element count {count:?}")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let Some(el) = elements.last_mut() else {
                    return Err(err(line_no, "property before any element".into()));
                };
                let ty_word = words.next();
                let prop = if ty_word == Some("list") {
                    let (Some(ct), Some(it)) = (words.next(), words.next()) else {
                        return Err(err(
                            line_no,
                            "expected \"property list COUNT_TYPE ITEM_TYPE NAME\"".into(),
                        ));
                    };
                    let ct = Ty::parse(ct)
                        .ok_or_else(|| err(line_no, format!("unknown type {ct:?}")))?;
                    let it = Ty::parse(it)
                        .ok_or_else(|| err(line_no, format!("unknown type {it:?}")))?;
                    if ct.is_float() {
                        return Err(err(line_no, "list count type must be an integer".into()));
                    }
                    Prop::List(ct, it)
                } else {
                    let t = ty_word.unwrap_or("");
                    Prop::Scalar(
                        Ty::parse(t).ok_or_else(|| err(line_no, format!("unknown type {t:?}")))?,
                    )
                };
                let (Some(name), None) = (words.next(), words.next()) else {
                    return Err(err(line_no, "expected one property name".into()));
                };
                el.props.push((name.to_string(), prop));
            }
            Some("end_header") => {
                let Some(encoding) = encoding else {
                    return Err(err(line_no, "end_header before the format line".into()));
                };
                return Ok(Header {
                    encoding,
                    elements,
                    body: pos,
                    body_line: line_no + 1,
                });
            }
            Some(w) => return Err(err(line_no, format!("unknown header keyword {w:?}"))),
        }
    }
}

fn short(s: &str) -> String {
    s.chars().take(40).collect()
}

/// Fails when the elements the header declares cannot fit in the `body` bytes after it, even at
/// their smallest (see the module doc), before anything is read or reserved.
fn check_counts(header: &Header, body: usize, file: &str) -> Result<()> {
    let mut need: u128 = 0;
    for (e_idx, el) in header.elements.iter().enumerate() {
        let min_each: usize = match header.encoding {
            Encoding::Ascii => 2 * el.props.len(),
            Encoding::Le | Encoding::Be => el
                .props
                .iter()
                .map(|(_, p)| match *p {
                    Prop::Scalar(t) | Prop::List(t, _) => t.size(),
                })
                .sum(),
        };
        need += el.count as u128 * min_each as u128;
        // An ascii file may omit the last line's newline.
        let have = body as u128 + (header.encoding == Encoding::Ascii) as u128;
        if need > have {
            return Err(Error::parse(
                file,
                format!("header, element {e_idx} ({})", el.name),
                format!(
                    "the header declares {} {} elements of at least {min_each} bytes each, more than the {body} bytes of data after the header can hold",
                    el.count, el.name
                ),
            ));
        }
    }
    Ok(())
}

fn classify(elements: &[Element], file: &str) -> Result<Vec<Kind>> {
    let mut have_vertex = false;
    let mut have_face = false;
    let mut kinds = Vec::with_capacity(elements.len());
    for (e_idx, el) in elements.iter().enumerate() {
        let place = || format!("header, element {e_idx} ({})", el.name);
        let kind = match el.name.as_str() {
            "vertex" if !have_vertex => {
                have_vertex = true;
                let mut xyz = [usize::MAX; 3];
                for (axis, n) in ["x", "y", "z"].iter().enumerate() {
                    let i = el
                        .props
                        .iter()
                        .position(|(name, _)| name == n)
                        .ok_or_else(|| {
                            Error::parse(file, place(), format!("vertex has no {n} property"))
                        })?;
                    if matches!(el.props[i].1, Prop::List(..)) {
                        return Err(Error::parse(
                            file,
                            place(),
                            format!("vertex property {n} is a list"),
                        ));
                    }
                    xyz[axis] = i;
                }
                Kind::Vertex { xyz }
            }
            "face" if !have_face => {
                have_face = true;
                let list = el
                    .props
                    .iter()
                    .position(|(name, p)| {
                        (name == "vertex_indices" || name == "vertex_index")
                            && matches!(p, Prop::List(..))
                    })
                    .ok_or_else(|| {
                        Error::parse(
                            file,
                            place(),
                            "face has no vertex_indices (or vertex_index) list property",
                        )
                    })?;
                if let Prop::List(_, it) = el.props[list].1 {
                    if it.is_float() {
                        return Err(Error::parse(
                            file,
                            place(),
                            "face vertex indices must be integers",
                        ));
                    }
                }
                Kind::Face { list }
            }
            "vertex" | "face" => {
                return Err(Error::parse(
                    file,
                    place(),
                    format!("second {} element", el.name),
                ))
            }
            _ => Kind::Other,
        };
        kinds.push(kind);
    }
    if have_face && !have_vertex {
        return Err(Error::parse(
            file,
            "header",
            "face element but no vertex element",
        ));
    }
    Ok(kinds)
}

/// Reserves at most what the remaining input could possibly hold, so a hostile count in the
/// header cannot make us allocate gigabytes up front.
fn reserve<T>(v: &mut Vec<T>, count: usize, remaining: usize, min_bytes_each: usize) {
    v.reserve(count.min(remaining / min_bytes_each.max(1)));
}

/// Fans polygon `face` (already range-checked) into `out`.
#[inline]
fn fan(face: &[u32], out: &mut Vec<[u32; 3]>) {
    if face.len() >= 3 {
        let v0 = face[0];
        for w in face[1..].windows(2) {
            out.push([v0, w[0], w[1]]);
        }
    }
}

fn read_ascii(
    bytes: &[u8],
    header: &Header,
    kinds: &[Kind],
    file: &str,
    out: &mut Out,
) -> Result<()> {
    let body = &bytes[header.body..];
    let text = match std::str::from_utf8(body) {
        Ok(t) => t,
        Err(e) => {
            let line = header.body_line
                + body[..e.valid_up_to()]
                    .iter()
                    .filter(|&&b| b == b'\n')
                    .count();
            return Err(Error::parse(
                file,
                format!("line {line}"),
                "invalid UTF-8 in ascii PLY data",
            ));
        }
    };
    let mut lines = text.split('\n');
    let mut line_no = header.body_line - 1;
    let mut face_buf: Vec<u32> = Vec::new();
    let eof = |line_no: usize, el: &Element, i: usize| {
        Error::parse(
            file,
            format!("line {line_no}"),
            format!(
                "unexpected end of file: the header declares {} {} elements, found {i}",
                el.count, el.name
            ),
        )
    };
    for (el, &kind) in header.elements.iter().zip(kinds) {
        match kind {
            Kind::Vertex { .. } => reserve(&mut out.positions, el.count, text.len(), 6),
            Kind::Face { .. } => reserve(&mut out.indices, el.count, text.len(), 8),
            Kind::Other => {}
        }
        if el.props.is_empty() {
            // No properties, no data (and no line), whatever the count.
            continue;
        }
        for i in 0..el.count {
            // Next non-blank line: blank lines are tolerated between elements.
            let line = loop {
                line_no += 1;
                match lines.next() {
                    None => return Err(eof(line_no - 1, el, i)),
                    Some(l) if l.trim_ascii().is_empty() => continue,
                    Some(l) => break l,
                }
            };
            let place = || format!("line {line_no}");
            let mut toks = line.split_ascii_whitespace();
            let mut xyz = [0f32; 3];
            face_buf.clear();
            for (p_idx, (pname, prop)) in el.props.iter().enumerate() {
                match *prop {
                    Prop::Scalar(ty) => {
                        let tok = toks.next().ok_or_else(|| {
                            Error::parse(
                                file,
                                place(),
                                format!("{} {i}: missing value for property {pname}", el.name),
                            )
                        })?;
                        if let Kind::Vertex { xyz: axes } = kind {
                            if let Some(a) = axes.iter().position(|&x| x == p_idx) {
                                // Parse straight to f32: correctly rounded from the decimal text.
                                let v: f32 = tok.parse().map_err(|_| {
                                    Error::parse(
                                        file,
                                        place(),
                                        format!(
                                            "vertex {i}: bad number {:?} for {pname}",
                                            short(tok)
                                        ),
                                    )
                                })?;
                                xyz[a] = v;
                                continue;
                            }
                        }
                        check_ascii_scalar(tok, ty).map_err(|m| {
                            Error::parse(
                                file,
                                place(),
                                format!("{} {i}: property {pname}: {m}", el.name),
                            )
                        })?;
                    }
                    Prop::List(ct, it) => {
                        let tok = toks.next().ok_or_else(|| {
                            Error::parse(
                                file,
                                place(),
                                format!("{} {i}: missing list count for {pname}", el.name),
                            )
                        })?;
                        let n = ascii_count(tok, ct).map_err(|m| {
                            Error::parse(
                                file,
                                place(),
                                format!("{} {i}: list count of {pname}: {m}", el.name),
                            )
                        })?;
                        let is_face_list = matches!(kind, Kind::Face { list } if list == p_idx);
                        for k in 0..n {
                            let tok = toks.next().ok_or_else(|| {
                                Error::parse(
                                    file,
                                    place(),
                                    format!(
                                        "{} {i}: list {pname} declares {n} items, found {k}",
                                        el.name
                                    ),
                                )
                            })?;
                            if is_face_list {
                                let idx = ascii_index(tok, it, out.vertex_count).map_err(|m| {
                                    Error::parse(file, place(), format!("face {i}: {m}"))
                                })?;
                                face_buf.push(idx);
                            } else {
                                check_ascii_scalar(tok, it).map_err(|m| {
                                    Error::parse(
                                        file,
                                        place(),
                                        format!("{} {i}: list {pname}: {m}", el.name),
                                    )
                                })?;
                            }
                        }
                    }
                }
            }
            if let Some(extra) = toks.next() {
                return Err(Error::parse(
                    file,
                    place(),
                    format!(
                        "{} {i}: unexpected extra value {:?} (the header declares {} properties)",
                        el.name,
                        short(extra),
                        el.props.len()
                    ),
                ));
            }
            match kind {
                Kind::Vertex { .. } => {
                    let p = Vec3::from_array(xyz);
                    if !p.is_finite() {
                        return Err(Error::parse(
                            file,
                            place(),
                            format!("vertex {i}: non-finite coordinate {p:?}"),
                        ));
                    }
                    out.positions.push(p);
                }
                Kind::Face { .. } => fan(&face_buf, &mut out.indices),
                Kind::Other => {}
            }
        }
    }
    for l in lines {
        line_no += 1;
        if !l.trim_ascii().is_empty() {
            return Err(Error::parse(
                file,
                format!("line {line_no}"),
                "data after the last element the header declares (wrong element count?)",
            ));
        }
    }
    Ok(())
}

fn check_ascii_scalar(tok: &str, ty: Ty) -> std::result::Result<(), String> {
    let ok = match ty {
        Ty::F32 | Ty::F64 => tok.parse::<f64>().is_ok(),
        Ty::I8 => tok.parse::<i8>().is_ok(),
        Ty::U8 => tok.parse::<u8>().is_ok(),
        Ty::I16 => tok.parse::<i16>().is_ok(),
        Ty::U16 => tok.parse::<u16>().is_ok(),
        Ty::I32 => tok.parse::<i32>().is_ok(),
        Ty::U32 => tok.parse::<u32>().is_ok(),
    };
    if ok {
        Ok(())
    } else {
        Err(format!("bad {ty:?} value {:?}", short(tok)))
    }
}

fn ascii_count(tok: &str, ty: Ty) -> std::result::Result<usize, String> {
    let v: i64 = tok
        .parse()
        .map_err(|_| format!("bad number {:?}", short(tok)))?;
    let max = match ty {
        Ty::I8 => i8::MAX as i64,
        Ty::U8 => u8::MAX as i64,
        Ty::I16 => i16::MAX as i64,
        Ty::U16 => u16::MAX as i64,
        Ty::I32 => i32::MAX as i64,
        _ => u32::MAX as i64,
    };
    if v < 0 || v > max {
        return Err(format!("count {v} out of range for {ty:?}"));
    }
    Ok(v as usize)
}

fn ascii_index(tok: &str, _ty: Ty, nv: u32) -> std::result::Result<u32, String> {
    let v: i64 = tok
        .parse()
        .map_err(|_| format!("bad vertex index {:?}", short(tok)))?;
    if v < 0 || v >= nv as i64 {
        return Err(format!(
            "vertex index {v} out of range (the file has {nv} vertices)"
        ));
    }
    Ok(v as u32)
}

/// Binary reader over the body with absolute byte offsets for errors.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    #[inline]
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.bytes.get(self.pos..self.pos.checked_add(n)?)?;
        self.pos += n;
        Some(s)
    }
}

#[inline]
fn read_f64<const BE: bool>(b: &[u8], ty: Ty) -> f64 {
    macro_rules! rd {
        ($t:ty, $n:expr) => {{
            let a: [u8; $n] = b[..$n].try_into().unwrap();
            (if BE {
                <$t>::from_be_bytes(a)
            } else {
                <$t>::from_le_bytes(a)
            }) as f64
        }};
    }
    match ty {
        Ty::I8 => b[0] as i8 as f64,
        Ty::U8 => b[0] as f64,
        Ty::I16 => rd!(i16, 2),
        Ty::U16 => rd!(u16, 2),
        Ty::I32 => rd!(i32, 4),
        Ty::U32 => rd!(u32, 4),
        Ty::F32 => rd!(f32, 4),
        Ty::F64 => rd!(f64, 8),
    }
}

#[inline]
fn read_int<const BE: bool>(b: &[u8], ty: Ty) -> i64 {
    macro_rules! rd {
        ($t:ty, $n:expr) => {{
            let a: [u8; $n] = b[..$n].try_into().unwrap();
            (if BE {
                <$t>::from_be_bytes(a)
            } else {
                <$t>::from_le_bytes(a)
            }) as i64
        }};
    }
    match ty {
        Ty::I8 => b[0] as i8 as i64,
        Ty::U8 => b[0] as i64,
        Ty::I16 => rd!(i16, 2),
        Ty::U16 => rd!(u16, 2),
        Ty::I32 => rd!(i32, 4),
        Ty::U32 => rd!(u32, 4),
        // Float index types are rejected by `classify`.
        Ty::F32 | Ty::F64 => -1,
    }
}

fn read_binary<const BE: bool>(
    bytes: &[u8],
    header: &Header,
    kinds: &[Kind],
    file: &str,
    out: &mut Out,
) -> Result<()> {
    let mut cur = Cursor {
        bytes,
        pos: header.body,
    };
    let mut face_buf: Vec<u32> = Vec::new();
    for (el, &kind) in header.elements.iter().zip(kinds) {
        let remaining = bytes.len() - cur.pos;
        match kind {
            Kind::Vertex { .. } => reserve(&mut out.positions, el.count, remaining, 3),
            Kind::Face { .. } => reserve(&mut out.indices, el.count, remaining, 4),
            Kind::Other => {}
        }
        if el.props.is_empty() {
            // No properties, no bytes: skipping is exact (looping `count` times could hang).
            continue;
        }
        for i in 0..el.count {
            let start = cur.pos;
            let trunc = |what: &str, at: usize| {
                Error::parse(
                    file,
                    format!("byte {at}"),
                    format!(
                        "unexpected end of file in {} {i} ({what}; the header declares {} {} elements, the file has {} bytes)",
                        el.name, el.count, el.name, bytes.len()
                    ),
                )
            };
            let mut xyz = [0f32; 3];
            face_buf.clear();
            for (p_idx, (pname, prop)) in el.props.iter().enumerate() {
                match *prop {
                    Prop::Scalar(ty) => {
                        let at = cur.pos;
                        let b = cur.take(ty.size()).ok_or_else(|| trunc(pname, at))?;
                        if let Kind::Vertex { xyz: axes } = kind {
                            if let Some(a) = axes.iter().position(|&x| x == p_idx) {
                                xyz[a] = read_f64::<BE>(b, ty) as f32;
                            }
                        }
                    }
                    Prop::List(ct, it) => {
                        let at = cur.pos;
                        let b = cur.take(ct.size()).ok_or_else(|| trunc(pname, at))?;
                        let n = read_int::<BE>(b, ct);
                        if n < 0 {
                            return Err(Error::parse(
                                file,
                                format!("byte {at}"),
                                format!("{} {i}: negative list count {n} for {pname}", el.name),
                            ));
                        }
                        let n = n as usize;
                        let at = cur.pos;
                        let items = cur
                            .take(n.saturating_mul(it.size()))
                            .ok_or_else(|| trunc(pname, at))?;
                        if matches!(kind, Kind::Face { list } if list == p_idx) {
                            for (k, c) in items.chunks_exact(it.size()).enumerate() {
                                let v = read_int::<BE>(c, it);
                                if v < 0 || v >= out.vertex_count as i64 {
                                    return Err(Error::parse(
                                        file,
                                        format!("byte {}", at + k * it.size()),
                                        format!(
                                            "face {i}: vertex index {v} out of range (the file has {} vertices)",
                                            out.vertex_count
                                        ),
                                    ));
                                }
                                face_buf.push(v as u32);
                            }
                        }
                    }
                }
            }
            match kind {
                Kind::Vertex { .. } => {
                    let p = Vec3::from_array(xyz);
                    if !p.is_finite() {
                        return Err(Error::parse(
                            file,
                            format!("byte {start}"),
                            format!("vertex {i}: non-finite coordinate {p:?}"),
                        ));
                    }
                    out.positions.push(p);
                }
                Kind::Face { .. } => fan(&face_buf, &mut out.indices),
                Kind::Other => {}
            }
        }
    }
    if cur.pos != bytes.len() {
        return Err(Error::parse(
            file,
            format!("byte {}", cur.pos),
            format!(
                "{} bytes after the last element the header declares (wrong element count?)",
                bytes.len() - cur.pos
            ),
        ));
    }
    Ok(())
}
