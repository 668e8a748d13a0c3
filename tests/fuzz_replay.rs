//! A bounded replay of the fuzz corpus (`tests/fuzz/corpus/scene/`, minimised by `cargo fuzz
//! cmin`) and of the hand-written hostile seeds it grew from (`tests/fuzz/seeds/`): every input
//! goes through `check_untrusted`, the function the fuzz target drives, under the default
//! limits. Each must answer (admitted or refused) without a panic; the examples must be admitted
//! as they are, and the seeds refused where they are at fault.

use std::path::{Path, PathBuf};

use drape::jobs::{Limits, Refusal, check_untrusted};

fn files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.is_file())
        .collect();
    files.sort();
    files
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn every_corpus_input_is_admitted_or_refused_without_a_panic() {
    let mut corpus = files(&root().join("tests/fuzz/corpus/scene"));
    assert!(corpus.len() >= 10, "the corpus holds {} inputs", corpus.len());
    corpus.extend(files(&root().join("tests/fuzz/seeds")));
    let limits = Limits::default();
    let (mut admitted, mut invalid, mut over_limit) = (0, 0, 0);
    for path in &corpus {
        let bytes = std::fs::read(path).unwrap();
        match check_untrusted(&bytes, &limits) {
            Ok(plan) => {
                assert!(plan.particles >= 1 && plan.steps >= 1, "{}: {plan:?}", path.display());
                admitted += 1;
            }
            Err(Refusal::Scene(_)) => invalid += 1,
            Err(Refusal::OverLimit(errors)) => {
                assert!(!errors.is_empty(), "{}", path.display());
                over_limit += 1;
            }
        }
    }
    println!("{} inputs: {admitted} admitted, {invalid} invalid, {over_limit} over the limits", corpus.len());
    assert_eq!(admitted + invalid + over_limit, corpus.len());
    assert!(admitted >= 10 && invalid >= 1 && over_limit >= 1, "{admitted} {invalid} {over_limit}");
}

#[test]
fn every_example_is_admitted_under_the_default_limits() {
    let examples: Vec<PathBuf> = files(&root().join("examples"))
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    assert_eq!(examples.len(), 17);
    for path in examples {
        let plan = check_untrusted(&std::fs::read(&path).unwrap(), &Limits::default())
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(plan.particles >= 2, "{}: {plan:?}", path.display());
    }
}

#[test]
fn hostile_scenes_are_refused_at_the_field_at_fault() {
    let corpus = root().join("tests/fuzz/seeds");
    let refusal =
        |name: &str| check_untrusted(&std::fs::read(corpus.join(name)).unwrap(), &Limits::default());
    match refusal("hostile_huge_cloth.json") {
        Err(Refusal::OverLimit(errors)) => assert_eq!(errors[0].pointer, "/bodies/0/resolution"),
        other => panic!("{other:?}"),
    }
    match refusal("hostile_wide_steps.json") {
        Err(Refusal::OverLimit(errors)) => {
            let pointers: Vec<&str> = errors.iter().map(|e| e.pointer.as_str()).collect();
            assert_eq!(pointers, ["/dt", "/output/fps"]);
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(refusal("hostile_deep_nesting.json"), Err(Refusal::Scene(_))));
    assert!(matches!(refusal("hostile_truncated.json"), Err(Refusal::Scene(_))));
}
