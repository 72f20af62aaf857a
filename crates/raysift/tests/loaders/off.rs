//! OFF loader cases.

use super::*;

#[test]
fn off_comments_fan_and_variants() {
    let dir = tempfile::tempdir().unwrap();
    let text = "OFF\n# a comment\n\n4 2 0\n0 0 0\n1 0 0 # trailing comment\n1 1 0\n0 1 0\n4 0 1 2 3\n3 3 2 1\n";
    let s = load(write(dir.path(), "a.off", text.as_bytes())).unwrap();
    assert_eq!(s.len(), 3);
    assert_eq!(tri(&s, 0), [sq(0), sq(1), sq(2)]);
    assert_eq!(tri(&s, 1), [sq(0), sq(2), sq(3)]);
    assert_eq!(tri(&s, 2), [sq(3), sq(2), sq(1)]);
    // COFF with colours, counts on the header line, CRLF, face colours, gzip.
    let coff = "COFF 4 1 0\r\n0 0 0 255 0 0 255\r\n1 0 0 255 0 0 255\r\n1 1 0 0 0 0 255\r\n0 1 0 0 0 0 255\r\n4 0 1 2 3 0.5 0.5 0.5\r\n";
    let s = load(write(dir.path(), "c.off.gz", &gzip(coff.as_bytes()))).unwrap();
    assert_eq!(s.len(), 2);
    assert_eq!(tri(&s, 1), [sq(0), sq(2), sq(3)]);
}

#[test]
fn off_malformed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ok = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let e = load_err(
        d,
        "badnum.off",
        ok.replace("1 0 0", "1 O 0").as_bytes(),
        "line 4",
    );
    assert!(e.contains("bad number") && e.contains("vertex 1"), "{e}");
    let e = load_err(
        d,
        "range.off",
        ok.replace("3 0 1 2", "3 0 1 3").as_bytes(),
        "line 6",
    );
    assert!(e.contains("out of range") && e.contains("face 0"), "{e}");
    let e = load_err(
        d,
        "nan.off",
        ok.replace("0 1 0", "0 nan 0").as_bytes(),
        "line 5",
    );
    assert!(e.contains("non-finite"), "{e}");
    let e = load_err(d, "trunc.off", &ok.as_bytes()[..ok.len() - 8], "line");
    assert!(e.contains("end of file") && e.contains("faces"), "{e}");
    let e = load_err(d, "empty.off", b"", "line 1");
    assert!(e.contains("empty"), "{e}");
    let e = load_err(d, "header.off", b"OBJ\n3 1 0\n", "line 1");
    assert!(e.contains("not an OFF"), "{e}");
    let e = load_err(
        d,
        "count.off",
        ok.replace("3 1 0", "3 2 0").as_bytes(),
        "line 6",
    );
    assert!(e.contains("declares 2 faces"), "{e}");
    let e = load_err(
        d,
        "extra.off",
        format!("{ok}3 2 1 0\n").as_bytes(),
        "line 7",
    );
    assert!(e.contains("wrong counts"), "{e}");
    load_err(
        d,
        "short_face.off",
        ok.replace("3 0 1 2", "4 0 1 2").as_bytes(),
        "line 6",
    );
    load_err(d, "4off.off", b"4OFF\n1 0 0\n0 0 0 0\n", "line 1");
}
