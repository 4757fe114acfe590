//! OBJ loading: file-order numbering with fan triangulation, counted exclusions, and
//! `FILE:LINE: message` errors for malformed files.

use std::path::PathBuf;

use lancer::mesh::{load_obj, TriStatus};
use lancer::Error;

fn write(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lancer-obj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn fan_triangulation_in_file_order_across_groups() {
    let p = write(
        "fan.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 0\n\
         o a\nf 1 2 3 4 5\ng b\nf 3 4 1\nusemtl missing\nf -5 -4 -3\n",
    );
    let m = load_obj(&p).unwrap();
    assert_eq!(m.len(), 5);
    let v = |i: usize| m.triangles[i].v.map(|p| (p.x, p.y));
    // Pentagon 1 2 3 4 5 → (1,2,3), (1,3,4), (1,4,5).
    assert_eq!(v(0), [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)]);
    assert_eq!(v(1), [(0.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
    assert_eq!(v(2), [(0.0, 0.0), (0.0, 1.0), (0.5, 1.5)]);
    assert_eq!(v(3), [(1.0, 1.0), (0.0, 1.0), (0.0, 0.0)]);
    assert_eq!(v(4), [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)]);
}

#[test]
fn bad_triangles_are_counted_and_keep_their_numbers() {
    let p = write(
        "bad.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nv 2 0 0\n\
         f 1 2 3\nf 1 2 4\nf 1 2 5\nf 1 2 9 3\nf 1 2\nf 2 3 1\n",
    );
    let m = load_obj(&p).unwrap();
    use TriStatus::*;
    assert_eq!(
        m.status,
        vec![Ok, NonFinite, Degenerate, OutOfRange, OutOfRange, Ok]
    );
    assert_eq!(m.short_faces, 1);
    assert_eq!(m.included(), vec![0, 5]);
    let s = m.exclusion_summary().unwrap();
    assert!(
        s.contains("1 with NaN/Inf")
            && s.contains("1 with zero area")
            && s.contains("2 with out-of-range"),
        "{s}"
    );
}

fn error_of(text: &str) -> String {
    let p = write("err.obj", text);
    match load_obj(&p) {
        Err(e @ Error::Input { .. }) => {
            assert_eq!(e.exit_code(), 2);
            e.to_string()
        }
        other => panic!("expected an input error, got {other:?}"),
    }
}

#[test]
fn malformed_files_name_the_line() {
    let e = error_of("v 0 0 0\nv 1 zero 0\n");
    assert!(e.ends_with("err.obj:2: 'zero' is not a number"), "{e}");
    let e = error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 x\n");
    assert!(
        e.ends_with("err.obj:5: 'x' in face corner 'x' is not an index"),
        "{e}"
    );
    let e = error_of("v 0 0\n");
    assert!(
        e.ends_with("err.obj:1: 'v' needs 3 numbers, found 2"),
        "{e}"
    );
    let e = error_of("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 3/1\n");
    assert!(e.contains("err.obj:4: texture coordinate index 1"), "{e}");
}
