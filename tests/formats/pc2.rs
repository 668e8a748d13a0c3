//! PC2, checked against its byte layout written out by hand, and against the JSON result.

use drape::output::Format;
use drape::run::Samples;

use crate::common::{Run, mixed_scene, numbers};

#[test]
fn pc2_matches_the_layout_byte_for_byte() {
    // A real run's recording with its frames replaced by two points over two frames whose bytes
    // are easy to write out.
    let mut run = Run::new(
        r#"{"duration": 0.1, "precision": "f32", "bodies": [{"type": "chain", "count": 2}],
                               "output": {"fps": 10}}"#,
    );
    assert_eq!(run.recording.frames.len(), 2);
    run.recording.frames.positions =
        Some(Samples::F32(vec![1.0, 2.0, 3.0, -0.5, 0.25, 0.0, 1.5, -2.0, 4.0, 0.0, 0.0, 1.0]));
    #[rustfmt::skip]
    let expected: Vec<u8> = [
        b"POINTCACHE2\0".as_slice(),
        &[1, 0, 0, 0],                // version 1
        &[2, 0, 0, 0],                // 2 points
        &[0x00, 0x00, 0x00, 0x00],    // start frame 0.0
        &[0x00, 0x00, 0x80, 0x3f],    // sample rate 1.0
        &[2, 0, 0, 0],                // 2 samples
        &[0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x40, 0x40], // 1, 2, 3
        &[0x00, 0x00, 0x00, 0xbf, 0x00, 0x00, 0x80, 0x3e, 0x00, 0x00, 0x00, 0x00], // -0.5, 0.25, 0
        &[0x00, 0x00, 0xc0, 0x3f, 0x00, 0x00, 0x00, 0xc0, 0x00, 0x00, 0x80, 0x40], // 1.5, -2, 4
        &[0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x3f], // 0, 0, 1
    ]
    .concat();
    assert_eq!(run.encode(Format::Pc2), expected);
}

#[test]
fn pc2_carries_the_json_positions_of_every_frame() {
    for precision in ["f32", "f64"] {
        let run = Run::new(&mixed_scene(precision, "all", &["positions"]));
        let bytes = run.encode(Format::Pc2);
        let frames = run.frames();
        let particles = run.recording.particles;
        let int = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        assert_eq!(&bytes[..12], b"POINTCACHE2\0");
        assert_eq!((int(12), int(16), int(28)), (1, particles as i32, frames.len() as i32));
        assert_eq!(bytes.len(), 32 + 12 * particles * frames.len());
        let read: Vec<f32> =
            bytes[32..].chunks_exact(4).map(|b| f32::from_le_bytes(b.try_into().unwrap())).collect();
        let json: Vec<f32> = frames.iter().flat_map(|f| numbers(&f["positions"])).map(|x| x as f32).collect();
        assert_eq!(read, json, "{precision}");
    }
}
