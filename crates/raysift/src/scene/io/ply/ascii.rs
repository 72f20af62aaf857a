//! The ascii PLY body: one element per line, tokens checked against their declared types, each
//! error naming the line.

use super::*;

pub(super) fn read_ascii(
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
            let mut color = [0f64; 3];
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
                        if let Kind::Vertex { xyz: axes, rgb } = kind {
                            if let Some(c) = rgb.and_then(|c| c.iter().position(|&x| x == p_idx)) {
                                check_ascii_scalar(tok, ty).map_err(|m| {
                                    Error::parse(
                                        file,
                                        place(),
                                        format!("vertex {i}: property {pname}: {m}"),
                                    )
                                })?;
                                let v: f64 = tok.parse().unwrap_or(f64::NAN);
                                color[c] = v * ty.color_scale();
                                continue;
                            }
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
                Kind::Vertex { rgb, .. } => {
                    let p = Vec3::from_array(xyz);
                    if !p.is_finite() {
                        return Err(Error::parse(
                            file,
                            place(),
                            format!("vertex {i}: non-finite coordinate {p:?}"),
                        ));
                    }
                    out.positions.push(p);
                    if rgb.is_some() {
                        let c =
                            vertex_color(color, i).map_err(|m| Error::parse(file, place(), m))?;
                        out.colors.push(c);
                    }
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
