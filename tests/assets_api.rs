//! `/assets` through the API: uploads of OBJ and GLB meshes, their content address, listing and
//! deletion, the limits, and scenes that name an asset in `POST /jobs`, `POST /simulate` and
//! `POST /sweeps`.

mod common;
mod deadline;

use axum::Router;
use axum::body::Body;
use axum::http::Request;
use common::*;
use drape::api::ApiConfig;
use drape::jobs::{AssetLimits, JobsConfig};
use serde_json::{Value, json};
use sha2::{Digest, Sha256};

/// A unit cube as Blender writes it: six quads as `v/vt/vn`, with statements drape ignores.
const CUBE_OBJ: &str = "# Blender 4.1\nmtllib cube.mtl\no Cube\n\
v 1 1 -1\nv 1 -1 -1\nv 1 1 1\nv 1 -1 1\nv -1 1 -1\nv -1 -1 -1\nv -1 1 1\nv -1 -1 1\n\
vn -0 1 -0\nvn -0 -0 1\nvn -1 -0 -0\nvn -0 -1 -0\nvn 1 -0 -0\nvn -0 -0 -1\n\
vt 0.625 0.5\nvt 0.875 0.5\nvt 0.875 0.75\nvt 0.625 0.75\ns 0\nusemtl Material\n\
f 1/1/1 5/2/1 7/3/1 3/4/1\nf 4/4/2 3/4/2 7/3/2 8/1/2\nf 8/1/3 7/3/3 5/2/3 6/1/3\n\
f 6/1/4 2/2/4 4/3/4 8/4/4\nf 2/1/5 1/2/5 3/3/5 4/4/5\nf 6/1/6 5/2/6 1/3/6 2/4/6\n";

/// The content address, computed here with the SHA-256 of the `sha2` crate.
fn sha256_id(bytes: &[u8]) -> String {
    let hex: String = Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect();
    format!("sha256:{hex}")
}

async fn upload(app: &Router, media_type: &str, bytes: &[u8]) -> Answer {
    let request =
        Request::post("/assets").header("content-type", media_type).body(Body::from(bytes.to_vec())).unwrap();
    send(app, request).await
}

fn app_with(assets: AssetLimits, max_particles: u64) -> Router {
    let mut config = jobs_config();
    config.assets = assets;
    config.limits.max_particles = max_particles;
    test_app(config, ApiConfig::default()).1
}

fn app() -> Router {
    app_with(AssetLimits::default(), JobsConfig::default().limits.max_particles)
}

/// A scene whose one body is the mesh of `asset`, falling for 0.1 s.
fn mesh_scene(asset: &str) -> String {
    json!({"duration": 0.1, "dt": 0.01, "bodies": [{"type": "mesh", "asset": asset, "mass": 1.0}],
           "output": {"frames": "final"}})
    .to_string()
}

async fn result_of(app: &Router, job: &Value) -> Value {
    let id = job["id"].as_str().unwrap();
    let ended = poll_until(app, id, is_final).await;
    assert_eq!(ended["status"], "succeeded", "{ended}");
    get(app, &format!("/jobs/{id}/result")).await.json()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_obj_upload_is_content_addressed_listed_used_by_a_job_and_deleted() {
    let app = app();
    let first = upload(&app, "model/obj", CUBE_OBJ.as_bytes()).await;
    assert_eq!(first.status, 201, "{}", first.text());
    let asset = first.json();
    let id = sha256_id(CUBE_OBJ.as_bytes());
    assert_eq!(asset["id"], id.as_str());
    // A cube: 8 corners, 6 quads split into 2 triangles each.
    assert_eq!((asset["vertices"].as_u64(), asset["triangles"].as_u64()), (Some(8), Some(12)));
    assert_eq!(asset["bytes"], CUBE_OBJ.len());
    assert_eq!(first.header("location"), Some(format!("/assets/{id}").as_str()));

    let again = upload(&app, "text/plain; charset=utf-8", CUBE_OBJ.as_bytes()).await;
    assert_eq!(again.status, 200, "{}", again.text());
    assert_eq!(again.json(), asset);

    let listed = get(&app, "/assets").await;
    assert_eq!(listed.status, 200);
    assert_eq!(listed.json()["assets"], json!([asset.clone()]));
    assert_eq!(get(&app, &format!("/assets/{id}")).await.json(), asset);

    let submitted = post_json(&app, "/jobs", &mesh_scene(&id)).await;
    assert_eq!(submitted.status, 202, "{}", submitted.text());
    // The job holds the mesh, not the reference: deleting the asset does not touch it.
    assert_eq!(delete(&app, &format!("/assets/{id}")).await.status, 204);
    let result = result_of(&app, &submitted.json()).await;
    assert_eq!(result["mesh"]["particles"], 8);
    assert_eq!(result["final"]["positions"].as_array().unwrap().len(), 24);
    assert_eq!(result["mesh"]["triangles"].as_array().unwrap().len(), 36);

    let gone = delete(&app, &format!("/assets/{id}")).await;
    assert_eq!(gone.status, 404);
    assert_eq!(gone.problem()["type"], "/problems/asset-not-found");
    assert_eq!(get(&app, &format!("/assets/{id}")).await.status, 404);
    assert_eq!(get(&app, "/assets").await.json()["assets"], json!([]));
    assert_eq!(get(&app, "/assets/cube.obj").await.status, 404);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simulate_and_sweeps_take_assets_and_limits_count_the_real_mesh() {
    let app = app();
    let id = upload(&app, "model/obj", CUBE_OBJ.as_bytes()).await.json()["id"].as_str().unwrap().to_string();
    let simulated = post_json(&app, "/simulate", &mesh_scene(&id)).await;
    assert_eq!(simulated.status, 200, "{}", simulated.text());
    assert_eq!(simulated.json()["mesh"]["particles"], 8);

    let sweep = json!({"scene": serde_json::from_str::<Value>(&mesh_scene(&id)).unwrap(),
                       "vary": {"/dt": [0.01, 0.005]}});
    let answer = post_json(&app, "/sweeps", &sweep.to_string()).await;
    assert_eq!(answer.status, 202, "{}", answer.text());

    // A mesh file over the triangle limit is refused at upload; a scene whose mesh passes the
    // particle limit, at admission.
    let few = drape::assets::MeshLimits { max_vertices: 8, max_triangles: 11 };
    let small = app_with(AssetLimits { mesh: few, ..AssetLimits::default() }, 7);
    let answer = upload(&small, "model/obj", CUBE_OBJ.as_bytes()).await;
    assert_eq!(answer.status, 422, "{}", answer.text());
    assert_eq!(
        answer.problem()["detail"],
        // Line 29 is the sixth quad, whose two triangles are the 11th and 12th.
        "OBJ line 29: more than 11 triangles, the most this server takes (--max-asset-triangles)"
    );
    let few = drape::assets::MeshLimits { max_vertices: 8, max_triangles: 12 };
    let small = app_with(AssetLimits { mesh: few, ..AssetLimits::default() }, 7);
    let id =
        upload(&small, "model/obj", CUBE_OBJ.as_bytes()).await.json()["id"].as_str().unwrap().to_string();
    let over = post_json(&small, "/jobs", &mesh_scene(&id)).await;
    assert_eq!(over.status, 422, "{}", over.text());
    let problem = over.problem();
    assert_eq!(problem["type"], "/problems/over-limit");
    assert!(problem["detail"].as_str().unwrap().contains("8 particles"), "{problem}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_references_are_422s_at_their_field() {
    let app = app();
    let unknown = sha256_id(b"never uploaded");
    let answer = post_json(&app, "/jobs", &mesh_scene(&unknown)).await;
    assert_eq!(answer.status, 422, "{}", answer.text());
    let problem = answer.problem();
    assert_eq!(problem["errors"][0]["pointer"], "/bodies/0/asset");
    assert_eq!(
        problem["errors"][0]["detail"],
        format!("no asset {unknown} is stored: upload it with POST /assets")
    );

    let file = r#"{"duration": 0.1, "bodies": [{"type": "mesh", "file": "cube.obj"}]}"#;
    let problem = post_json(&app, "/simulate", file).await.problem();
    assert_eq!(problem["status"], 422);
    assert_eq!(problem["errors"][0]["pointer"], "/bodies/0/file");
    assert!(
        problem["errors"][0]["detail"].as_str().unwrap().starts_with("the server reads no files"),
        "{problem}"
    );

    let id = upload(&app, "model/obj", CUBE_OBJ.as_bytes()).await.json()["id"].as_str().unwrap().to_string();
    let both = json!({"duration": 0.1, "bodies": [{"type": "mesh", "asset": id, "triangles": [0, 1, 2]}]});
    let problem = post_json(&app, "/jobs", &both.to_string()).await.problem();
    assert_eq!(problem["errors"][0]["pointer"], "/bodies/0/asset");

    let sweep = json!({"scene": {"duration": 0.1, "bodies": [{"type": "mesh", "asset": unknown}]},
                       "vary": {"/dt": [0.01]}});
    let problem = post_json(&app, "/sweeps", &sweep.to_string()).await.problem();
    assert_eq!(problem["errors"][0]["pointer"], "/scene/bodies/0/asset");
}

/// A GLB file of one triangle whose index accessor (1) claims more elements than its view holds.
fn glb_with_a_long_index_accessor() -> Vec<u8> {
    let mut bin = Vec::new();
    for x in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        bin.extend_from_slice(&x.to_le_bytes());
    }
    bin.extend_from_slice(&[0, 0, 1, 0, 2, 0, 0, 0]);
    let document = json!({
        "asset": {"version": "2.0"},
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5123, "count": 30, "type": "SCALAR"},
        ],
        "bufferViews": [{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
        "buffers": [{"byteLength": 44}],
    });
    let mut json = serde_json::to_vec(&document).unwrap();
    json.resize(json.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    for word in [2, total as u32, json.len() as u32] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_files_are_422s_naming_the_obj_line_or_the_glb_accessor() {
    let app = app();
    let answer = upload(&app, "model/obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").await;
    assert_eq!(answer.status, 422, "{}", answer.text());
    let problem = answer.problem();
    assert_eq!(problem["type"], "/problems/invalid-mesh");
    assert_eq!(problem["line"], 4);
    assert_eq!(problem["detail"], "OBJ line 4: face corner `4` names a vertex not defined above (3 are)");

    let answer = upload(&app, "model/gltf-binary", &glb_with_a_long_index_accessor()).await;
    assert_eq!(answer.status, 422, "{}", answer.text());
    let problem = answer.problem();
    assert_eq!(problem["at"], "accessor 1");
    assert_eq!(
        problem["detail"],
        "GLB accessor 1: 30 elements from byteOffset 0 run past its bufferView 1 of 6 bytes"
    );

    let problem = upload(&app, "model/gltf-binary", CUBE_OBJ.as_bytes()).await.problem();
    assert_eq!(problem["detail"], "GLB header: the file does not start with `glTF`");

    let answer = upload(&app, "application/json", b"{}").await;
    assert_eq!(answer.status, 415);
    assert_eq!(answer.problem()["title"], "The body must be a mesh file");
    assert_eq!(get(&app, "/assets").await.json()["assets"], json!([]));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn uploads_over_the_size_or_the_store_limits_are_413s_naming_the_limit() {
    let small = AssetLimits { max_bytes: 100, max_assets: 1, ..AssetLimits::default() };
    let app = app_with(small, JobsConfig::default().limits.max_particles);
    let answer = upload(&app, "model/obj", CUBE_OBJ.as_bytes()).await;
    assert_eq!(answer.status, 413, "{}", answer.text());
    let problem = answer.problem();
    assert_eq!(problem["type"], "/problems/asset-over-limit");
    assert_eq!(
        problem["detail"],
        format!("the file has {} bytes; this server takes at most 100 (--max-asset-bytes)", CUBE_OBJ.len())
    );

    let triangle = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    assert_eq!(upload(&app, "model/obj", triangle).await.status, 201);
    let answer = upload(&app, "model/obj", b"v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n").await;
    assert_eq!(answer.status, 413, "{}", answer.text());
    assert!(answer.problem()["detail"].as_str().unwrap().contains("--max-assets 1"), "{}", answer.text());
    // The one already stored is still found.
    assert_eq!(upload(&app, "model/obj", triangle).await.status, 200);
}
