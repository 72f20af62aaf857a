//! Replays the committed fuzz corpus (`fuzz/corpus/<target>/`) and the inputs that once crashed a
//! target (`fuzz/regressions/<target>/`) through the same function the fuzz targets call
//! (`fuzz/src/lib.rs`, included here), on the stable toolchain without cargo-fuzz. Every input
//! must give `Ok` or an error naming the input; a panic fails the test. See docs/fuzzing.md.

#[path = "../../../fuzz/src/lib.rs"]
#[allow(dead_code)]
mod fuzz_entry;

use fuzz_entry::{run, Target};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz")
}

fn files(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<PathBuf> = rd
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    v.sort();
    v
}

#[test]
fn corpus_and_regressions_replay_without_panic() {
    let start = Instant::now();
    let mut total = 0;
    for t in Target::ALL {
        let corpus = files(&fuzz_dir().join("corpus").join(t.name()));
        assert!(
            !corpus.is_empty(),
            "fuzz/corpus/{} is empty or missing",
            t.name()
        );
        let regressions = files(&fuzz_dir().join("regressions").join(t.name()));
        for p in corpus.iter().chain(&regressions) {
            let data = std::fs::read(p).unwrap();
            let t0 = Instant::now();
            let r = std::panic::catch_unwind(|| run(t, &data));
            assert!(r.is_ok(), "{}: {} panicked", t.name(), p.display());
            // libFuzzer's -timeout for the recorded runs is 10 s; a replay is far quicker.
            assert!(
                t0.elapsed().as_secs_f64() < 5.0,
                "{}: {} took {:?}",
                t.name(),
                p.display(),
                t0.elapsed()
            );
            total += 1;
        }
    }
    eprintln!("replayed {total} inputs in {:?}", start.elapsed());
}
