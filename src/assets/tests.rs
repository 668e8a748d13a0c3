use serde_json::json;

use super::*;

const LIMITS: MeshLimits = MeshLimits { max_vertices: 1000, max_triangles: 1000 };

/// A unit cube as Blender writes it: `o`, `vt`, `vn`, `s`, `usemtl`, six quads as `v/vt/vn`.
const CUBE_OBJ: &str = "# Blender 4.1\nmtllib cube.mtl\no Cube\n\
v 1 1 -1\nv 1 -1 -1\nv 1 1 1\nv 1 -1 1\nv -1 1 -1\nv -1 -1 -1\nv -1 1 1\nv -1 -1 1\n\
vn -0 1 -0\nvn -0 -0 1\nvn -1 -0 -0\nvn -0 -1 -0\nvn 1 -0 -0\nvn -0 -0 -1\n\
vt 0.625 0.5\nvt 0.875 0.5\nvt 0.875 0.75\nvt 0.625 0.75\n\
s 0\nusemtl Material\n\
f 1/1/1 5/2/1 7/3/1 3/4/1\nf 4/4/2 3/4/2 7/3/2 8/1/2\nf 8/1/3 7/3/3 5/2/3 6/1/3\n\
f 6/1/4 2/2/4 4/3/4 8/4/4\nf 2/1/5 1/2/5 3/3/5 4/4/5\nf 6/1/6 5/2/6 1/3/6 2/4/6\n";

#[test]
fn a_blender_cube_reads_as_twelve_triangles_split_into_fans() {
    let mesh = read_obj(CUBE_OBJ.as_bytes(), LIMITS).unwrap();
    assert_eq!(mesh.vertex_count(), 8);
    assert_eq!(mesh.triangle_count(), 12);
    assert_eq!(&mesh.vertices[..6], &[1.0, 1.0, -1.0, 1.0, -1.0, -1.0]);
    // The first quad 1 5 7 3 (1-based) is split around its first corner: (1 5 7) and (1 7 3).
    assert_eq!(&mesh.triangles[..6], &[0, 4, 6, 0, 6, 2]);
    // Every triangle of a cube's face has area 2 (half of a 2 × 2 square): 24 in all.
    let v = |i: u32| glam::DVec3::from_slice(&mesh.vertices[3 * i as usize..]);
    let area: f64 =
        mesh.triangles.chunks(3).map(|t| 0.5 * (v(t[1]) - v(t[0])).cross(v(t[2]) - v(t[0])).length()).sum();
    assert_eq!(area, 24.0);
}

#[test]
fn every_corner_form_and_negative_indices_name_the_same_vertices() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvn 0 0 1\n\
                f 1 2 3\nf 1/1 2/1 4/1\nf 1//1 3//1 4//1\nf -3/1/1 -2/1/1 -1/1/1\n";
    let mesh = read_obj(text.as_bytes(), LIMITS).unwrap();
    assert_eq!(mesh.triangles, vec![0, 1, 2, 0, 1, 3, 0, 2, 3, 1, 2, 3]);
    assert_eq!(mesh.vertex_count(), 4);
}

#[test]
fn a_pentagon_is_a_fan_of_three_and_unused_vertices_are_dropped() {
    let text = "v 9 9 9\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0.5 1.5 0\nv 0 1 0\r\nf 2 3 4 5 6\r\n";
    let mesh = read_obj(text.as_bytes(), LIMITS).unwrap();
    assert_eq!(mesh.triangles, vec![0, 1, 2, 0, 2, 3, 0, 3, 4]);
    assert_eq!(&mesh.vertices[..3], &[0.0, 0.0, 0.0]);
    assert_eq!(mesh.vertex_count(), 5);
}

#[test]
fn bad_obj_files_name_their_line_and_reason() {
    let cases: [(&str, usize, &str); 9] = [
        ("v 0 0 0\nv 1 0\n", 2, "a vertex needs x, y and z; z is missing"),
        ("v 0 0 0\nv 1 zero 0\n", 2, "vertex y `zero` is not a number"),
        ("v 0 0 2e6\n", 1, "vertex z 2e6 is not finite within ±1e6"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", 4, "a face needs at least 3 corners; it has 2"),
        (
            "v 0 0 0\nv 1 0 0\n\nf 1 2 3\nv 0 1 0\n",
            4,
            "face corner `3` names a vertex not defined above (2 are)",
        ),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "face corner `0`: vertex indices start at 1"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n",
            4,
            "face corner `-4` names a vertex not defined above (3 are)",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2\n",
            4,
            "the face repeats a vertex (triangle of vertices 1, 2, 2)",
        ),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf a/1 2 3\n", 4, "face corner `a/1` does not start with a vertex index"),
    ];
    for (text, line, reason) in cases {
        let error = read_obj(text.as_bytes(), LIMITS).unwrap_err();
        assert_eq!(error, ObjError { line, reason: reason.into() }, "{text:?}");
    }
    let no_faces = read_obj(b"v 0 0 0\n", LIMITS).unwrap_err();
    assert_eq!(no_faces.to_string(), "OBJ line 0: the file has no faces (`f` lines)");
    let not_utf8 = read_obj(b"v 0 0 0\nv \xff 0 0\n", LIMITS).unwrap_err();
    assert_eq!(not_utf8, ObjError { line: 2, reason: "the text is not UTF-8".into() });
}

#[test]
fn obj_files_over_the_limits_are_refused_at_the_line_that_passes_them() {
    let small = MeshLimits { max_vertices: 3, max_triangles: 1 };
    let four_vertices = read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n", small).unwrap_err();
    assert_eq!(
        four_vertices,
        ObjError {
            line: 4,
            reason: "more than 3 vertices, the most this server takes (--max-particles)".into()
        }
    );
    let quad = read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 3 2 1\n", small).unwrap_err();
    assert_eq!(
        quad,
        ObjError {
            line: 5,
            reason: "more than 1 triangles, the most this server takes (--max-asset-triangles)".into()
        }
    );
}

/// A GLB file from a JSON document and a binary chunk, laid out as the specification says.
fn glb(document: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(document).unwrap();
    json.resize(json.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// One triangle (0,0,0), (1,0,0), (0,1,0) with `u16` indices, used by a parent node translated
/// by (0, 0, 5) and its child scaled by 2 about its origin.
fn triangle_glb() -> (serde_json::Value, Vec<u8>) {
    let mut bin = Vec::new();
    for x in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        bin.extend_from_slice(&x.to_le_bytes());
    }
    for i in [0u16, 1, 2] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    let document = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"translation": [0, 0, 5], "children": [1]},
            {"scale": [2, 2, 2], "mesh": 0},
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6},
        ],
        "buffers": [{"byteLength": 44}],
    });
    (document, bin)
}

#[test]
fn a_glb_triangle_is_placed_by_its_node_and_its_parent() {
    let (document, bin) = triangle_glb();
    let mesh = read_glb(&glb(&document, &bin), LIMITS).unwrap();
    assert_eq!(mesh.vertices, vec![0.0, 0.0, 5.0, 2.0, 0.0, 5.0, 0.0, 2.0, 5.0]);
    assert_eq!(mesh.triangles, vec![0, 1, 2]);
}

#[test]
fn bad_glb_files_name_their_accessor_or_chunk() {
    let (document, bin) = triangle_glb();
    let broken = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut document = document.clone();
        edit(&mut document);
        read_glb(&glb(&document, &bin), LIMITS).unwrap_err().to_string()
    };
    assert_eq!(
        broken(&|d| d["accessors"][1]["count"] = json!(6)),
        "GLB accessor 1: 6 elements from byteOffset 0 run past its bufferView 1 of 6 bytes"
    );
    assert_eq!(
        broken(&|d| d["accessors"][0]["componentType"] = json!(5123)),
        "GLB accessor 0: componentType 5123 where float (5126) is needed"
    );
    assert_eq!(
        broken(&|d| d["accessors"][1]["type"] = json!("VEC2")),
        "GLB accessor 1: type VEC2 where SCALAR is needed"
    );
    assert_eq!(
        broken(&|d| d["bufferViews"][0]["byteLength"] = json!(4000)),
        "GLB bufferView 0: bytes 0 to 4000 run past the binary chunk of 44 bytes"
    );
    assert_eq!(
        broken(&|d| d["nodes"][1]["children"] = json!([0])),
        "GLB node 0: the node is its own ancestor"
    );
    assert_eq!(
        broken(&|d| d["buffers"][0]["uri"] = json!("mesh.bin")),
        "GLB JSON chunk: buffer 0 is not the GLB's binary chunk; other files are not read"
    );
    let mut bad_index = bin.clone();
    bad_index[38..40].copy_from_slice(&7u16.to_le_bytes());
    assert_eq!(
        read_glb(&glb(&document, &bad_index), LIMITS).unwrap_err().to_string(),
        "GLB accessor 1: index 7 of triangle 0 is past the 3 positions"
    );
    let file = glb(&document, &bin);
    assert_eq!(read_glb(&file[..file.len() - 4], LIMITS).unwrap_err().place, GlbPlace::Header);
    let mut cut = file.clone();
    cut[12..16].copy_from_slice(&100_000u32.to_le_bytes());
    assert_eq!(
        read_glb(&cut, LIMITS).unwrap_err(),
        GlbError { place: GlbPlace::Chunk(0), reason: "100000 bytes run past the end of the file".into() }
    );
    assert_eq!(read_glb(b"OBJ?", LIMITS).unwrap_err().reason, "the file does not start with `glTF`");
    let one_triangle = MeshLimits { max_vertices: 2, max_triangles: 1 };
    assert_eq!(
        read_glb(&file, one_triangle).unwrap_err().to_string(),
        "GLB accessor 0: the file has more than 2 vertices, the most this server takes (--max-particles)"
    );
}

#[test]
fn hostile_glb_counts_are_refused_before_anything_is_allocated() {
    let (mut document, bin) = triangle_glb();
    document["accessors"][1]["count"] = json!(u64::MAX);
    document["bufferViews"][1]["byteStride"] = json!(4);
    let error = read_glb(&glb(&document, &bin), LIMITS).unwrap_err();
    assert_eq!(error.place, GlbPlace::Accessor(1));
}

#[test]
fn the_compact_form_gives_back_the_same_mesh() {
    let mesh = read_obj(CUBE_OBJ.as_bytes(), LIMITS).unwrap();
    let compact = mesh.to_compact();
    assert_eq!(Mesh::from_compact(&compact).unwrap(), mesh);
    assert!(Mesh::from_compact(&compact[..compact.len() / 2]).is_err());
}

#[test]
fn an_asset_id_is_the_sha256_of_the_bytes() {
    // FIPS 180-2, appendix B.1: SHA-256("abc").
    assert_eq!(asset_id(b"abc"), "sha256:ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
    assert!(is_asset_id(&asset_id(b"abc")));
    assert!(!is_asset_id("sha256:BA7816BF8F01CFEA414140DE5DAE2223B00361A396177A9CB410FF61F20015AD"));
}

#[test]
fn media_types_and_extensions_choose_the_reader() {
    assert_eq!(MeshFormat::from_media_type("model/obj"), Some(MeshFormat::Obj));
    assert_eq!(MeshFormat::from_media_type("text/plain; charset=utf-8"), Some(MeshFormat::Obj));
    assert_eq!(MeshFormat::from_media_type("model/gltf-binary"), Some(MeshFormat::Glb));
    assert_eq!(MeshFormat::from_media_type("application/json"), None);
    assert_eq!(MeshFormat::from_path(std::path::Path::new("a/b.GLB")), Some(MeshFormat::Glb));
}

#[test]
fn references_are_found_in_mesh_bodies_and_colliders_and_replaced_by_the_mesh() {
    let id = asset_id(b"abc");
    let mut scene = json!({
        "bodies": [{"type": "cloth"}, {"type": "mesh", "asset": id, "mass": 2}],
        "colliders": [{"type": "mesh", "file": "chair.obj"}, {"type": "sphere", "asset": "ignored"}],
    });
    let references = referenced_assets(&scene, "").unwrap();
    let pointers: Vec<_> = references.iter().map(|r| (r.pointer.as_str(), r.source.clone())).collect();
    assert_eq!(
        pointers,
        [
            ("/bodies/1/asset", MeshSource::Asset(id.clone())),
            ("/colliders/0/file", MeshSource::File("chair.obj".into()))
        ]
    );
    let mesh = read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", LIMITS).unwrap();
    put_mesh(&mut scene, &references[0], &mesh);
    assert_eq!(
        scene["bodies"][1],
        json!({"type": "mesh", "mass": 2, "vertices": [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "triangles": [0, 1, 2]})
    );
}

#[test]
fn a_reference_beside_inline_vertices_or_another_reference_is_refused() {
    let id = asset_id(b"abc");
    let scene = json!({"bodies": [
        {"type": "mesh", "asset": id, "vertices": [0, 0, 0]},
        {"type": "mesh", "asset": "sha256:12"},
        {"type": "mesh", "asset": id, "file": "a.obj"},
    ]});
    let errors = referenced_assets(&scene, "/scene").unwrap_err();
    let pointers: Vec<_> = errors.iter().map(|e| e.pointer.as_str()).collect();
    assert_eq!(pointers, ["/scene/bodies/0/asset", "/scene/bodies/1/asset", "/scene/bodies/2/file"]);
    assert!(errors[0].detail.contains("remove `vertices` and `triangles`"), "{}", errors[0].detail);
}

#[test]
fn files_are_read_relative_to_the_scene_and_assets_are_refused_on_the_command_line() {
    let directory = tempfile::tempdir().unwrap();
    std::fs::write(directory.path().join("cube.obj"), CUBE_OBJ).unwrap();
    std::fs::write(directory.path().join("bad.obj"), "v 0 0 0\nf 1 1 1\n").unwrap();
    let mut scene = json!({"bodies": [{"type": "mesh", "file": "cube.obj"}]});
    resolve_files(&mut scene, "", directory.path(), LIMITS).unwrap();
    assert_eq!(scene["bodies"][0]["triangles"].as_array().unwrap().len(), 36);
    let mut scene = json!({"bodies": [
        {"type": "mesh", "file": "bad.obj"},
        {"type": "mesh", "asset": asset_id(b"abc")},
        {"type": "mesh", "file": "cube.stl"},
    ]});
    let errors = resolve_files(&mut scene, "", directory.path(), LIMITS).unwrap_err();
    assert_eq!(errors.len(), 3);
    assert_eq!(errors[0].pointer, "/bodies/0/file");
    assert!(
        errors[0]
            .detail
            .ends_with("bad.obj: OBJ line 2: the face repeats a vertex (triangle of vertices 1, 1, 1)"),
        "{}",
        errors[0].detail
    );
    assert_eq!(errors[1].pointer, "/bodies/1/asset");
    assert_eq!(errors[2].detail, "the file must end in .obj or .glb");
}

#[test]
fn every_damaged_copy_of_a_glb_is_read_or_refused_without_a_panic() {
    let (document, bin) = triangle_glb();
    let file = glb(&document, &bin);
    let mut read = 0;
    for at in 12..file.len() {
        for value in [0x00, 0x7f, 0xff] {
            let mut damaged = file.clone();
            damaged[at] = value;
            // Ok or Err are both answers; a panic fails the test.
            read += usize::from(read_glb(&damaged, LIMITS).is_ok());
        }
    }
    // A flip inside the positions leaves a readable triangle, so some copies are read.
    assert!(read > 0);
    for end in 0..file.len() {
        assert!(read_glb(&file[..end], LIMITS).is_err(), "a GLB cut at {end} bytes");
    }
}

#[test]
fn every_prefix_of_an_obj_is_read_or_refused_without_a_panic() {
    for end in 0..CUBE_OBJ.len() {
        let prefix = &CUBE_OBJ.as_bytes()[..end];
        if let Ok(mesh) = read_obj(prefix, LIMITS) {
            assert!(mesh.triangles.iter().all(|&i| (i as usize) < mesh.vertex_count()));
        }
    }
}
