//! Encoding throughput of each result format, in bytes of output per second, for a 128 × 128
//! cloth with 300 frames.
//!
//! Simulating 300 frames of that cloth would take far longer than encoding them, and an encoder's
//! cost does not depend on where the numbers came from, so the recording is made from a short
//! real run (its mesh, bodies and stats) whose frames are then filled with a travelling wave.

// `criterion_group!` defines a public function without documentation.
#![allow(missing_docs)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use drape::output::{Format, encode};
use drape::run::{Control, Recording, Samples, execute};
use drape::scene::{FrameSelection, Scene};

const FRAMES: usize = 300;

fn recording(precision: &str, fields: &[&str]) -> Recording {
    let scene = format!(
        r#"{{"duration": 0.001, "precision": "{precision}",
             "bodies": [{{"type": "cloth", "resolution": [128, 128], "pin": [[0, 0], [127, 0]]}}],
             "output": {{"frames": "final", "fields": {}}}}}"#,
        serde_json::to_string(fields).unwrap()
    );
    let scene = Scene::from_json(scene.as_bytes()).unwrap();
    let mut recording = execute(&scene.compile(), &Control::new());
    let base = recording.frames.positions.as_ref().unwrap().to_f64();
    recording.selection = FrameSelection::All;
    let f = &mut recording.frames;
    f.times = (0..FRAMES).map(|k| k as f64 / 30.0).collect();
    let wave = |scale: f64| -> Vec<f64> {
        (0..FRAMES)
            .flat_map(|k| {
                base.iter().enumerate().map(move |(i, &x)| x + scale * ((i + 7 * k) as f64 * 0.01).sin())
            })
            .collect()
    };
    let samples = |values: Vec<f64>| match precision {
        "f32" => Samples::F32(values.into_iter().map(|x| x as f32).collect()),
        _ => Samples::F64(values),
    };
    f.positions = Some(samples(wave(0.01)));
    if f.velocities.is_some() {
        f.velocities = Some(samples(wave(0.5)));
    }
    if f.normals.is_some() {
        f.normals =
            Some(samples((0..FRAMES * base.len()).map(|i| if i % 3 == 1 { 1.0 } else { 0.0 }).collect()));
    }
    recording
}

fn encode_formats(c: &mut Criterion) {
    let mut group = c.benchmark_group("encode 128x128 cloth, 300 frames");
    group.sample_size(10);
    let positions = recording("f32", &["positions"]);
    let fields = recording("f32", &["positions", "velocities", "normals"]);
    let cases = [
        (Format::Json, &positions),
        (Format::Glb, &positions),
        (Format::Obj, &positions),
        (Format::Npy, &positions),
        (Format::Npz, &fields),
        (Format::Pc2, &positions),
    ];
    for (format, recording) in cases {
        let mut bytes = Vec::new();
        encode(recording, format, &mut bytes).unwrap();
        group.throughput(Throughput::Bytes(bytes.len() as u64));
        let mut out = Vec::with_capacity(bytes.len());
        group.bench_function(format.name(), |b| {
            b.iter(|| {
                out.clear();
                encode(recording, format, &mut out).unwrap();
            })
        });
    }
    group.finish();
}

criterion_group!(benches, encode_formats);
criterion_main!(benches);
