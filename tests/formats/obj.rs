//! OBJ, read back by `tobj` (built with `f64` numbers, so nothing is rounded on the way in).

use drape::output::Format;

use crate::common::{Run, mixed_scene, numbers};

fn check_against_json(run: &Run) {
    let text = run.encode(Format::Obj);
    let options = tobj::LoadOptions {
        single_index: false,
        triangulate: false,
        ignore_points: true,
        ignore_lines: false,
    };
    let (models, _) =
        tobj::load_obj_buf(&mut text.as_slice(), &options, |_| Err(tobj::LoadError::OpenFileFailed))
            .expect("tobj reads the OBJ");
    let last = run.last();
    let positions = numbers(&last["positions"]);
    let normals = last.get("normals").map(numbers);
    let triangles = run.triangles();
    let bodies = run.bodies();
    assert_eq!(models.len(), bodies.len());
    let f32_run = run.precision() == "f32";
    // The number as the run's precision holds it: tobj parses f64, which is exact for the
    // shortest decimal of an f64, and rounds back to the same f32 for an f32 run.
    let same = |read: f64, json: f64| {
        if f32_run { read as f32 == json as f32 } else { read.to_bits() == json.to_bits() }
    };

    for (model, (name, offset, count)) in models.iter().zip(&bodies) {
        assert_eq!(&model.name, name);
        let mesh = &model.mesh;
        // tobj keeps each object's vertices in order of first use, so compare through the
        // indices: each face corner must be the JSON's particle.
        let (corners, chain): (Vec<usize>, bool) = {
            let body: Vec<[usize; 3]> =
                triangles.iter().filter(|t| (*offset..offset + count).contains(&t[0])).copied().collect();
            if body.is_empty() {
                assert_eq!(mesh.face_arities, [*count as u32], "{name}: one line through the chain");
                ((*offset..offset + count).collect(), true)
            } else {
                // tobj leaves the arities out when every face is a triangle.
                assert!(mesh.face_arities.iter().all(|&a| a == 3), "{name}: triangles only");
                assert_eq!(mesh.indices.len(), 3 * body.len(), "{name}: faces");
                (body.into_iter().flatten().collect(), false)
            }
        };
        assert_eq!(mesh.indices.len(), corners.len());
        for (corner, (&read, &particle)) in mesh.indices.iter().zip(&corners).enumerate() {
            for a in 0..3 {
                let (read, json) = (mesh.positions[3 * read as usize + a], positions[3 * particle + a]);
                assert!(same(read, json), "{name}: corner {corner}, particle {particle}: {read} vs {json}");
            }
        }
        if chain {
            continue;
        }
        assert_eq!(mesh.normal_indices.len(), corners.len(), "{name}: a normal per corner");
        for (&read, &particle) in mesh.normal_indices.iter().zip(&corners) {
            let n: Vec<f64> = (0..3).map(|a| mesh.normals[3 * read as usize + a]).collect();
            match &normals {
                Some(json) => {
                    (0..3).for_each(|a| assert!(same(n[a], json[3 * particle + a]), "{name}: normal"))
                }
                None => {
                    let length = n.iter().map(|x| x * x).sum::<f64>().sqrt();
                    assert!((length - 1.0).abs() < 1e-6, "{name}: computed normal {n:?} is not unit");
                }
            }
        }
    }
}

#[test]
fn tobj_reads_back_the_last_frame_of_an_f64_run() {
    check_against_json(&Run::new(&mixed_scene("f64", "all", &["positions"])));
}

#[test]
fn tobj_reads_back_an_f32_run_with_its_normals() {
    check_against_json(&Run::new(&mixed_scene("f32", "final", &["positions", "normals"])));
}
