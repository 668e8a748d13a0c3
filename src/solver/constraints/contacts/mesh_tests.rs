//! Mesh colliders against brute force and the known answers: the hierarchy finds what a search
//! of every triangle finds, a closed mesh is told from an open one, fast particles stop at a
//! sheet, particles inside a solid go out, and contacts bounce and slide as on a plane.

use std::collections::HashMap;
use std::sync::Arc;

use glam::DVec3;

use super::triangle::{self, Feature};
use super::triangle_bvh::TriangleBvh;
use super::*;
use crate::solver::integrators::IntegratorKind;
use crate::solver::model::Model;
use crate::solver::simulation::{Config, Simulation};

/// An icosahedron's faces subdivided `levels` times and pushed onto the sphere, wound outwards.
pub(crate) fn icosphere(center: DVec3, radius: f64, levels: usize) -> TriangleSurface {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut vertices: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .map(|p| DVec3::from_array(p).normalize())
    .to_vec();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut middle: HashMap<(u32, u32), u32> = HashMap::new();
        let mut split = |a: u32, b: u32, vertices: &mut Vec<DVec3>| {
            *middle.entry((a.min(b), a.max(b))).or_insert_with(|| {
                vertices.push((vertices[a as usize] + vertices[b as usize]).normalize());
                vertices.len() as u32 - 1
            })
        };
        triangles = triangles
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) =
                    (split(a, b, &mut vertices), split(b, c, &mut vertices), split(c, a, &mut vertices));
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    TriangleSurface { vertices: vertices.iter().map(|&v| center + v * radius).collect(), triangles }
}

/// A flat square sheet of `2 n²` triangles at height `y`, `size` wide, centred on the y axis.
pub(crate) fn sheet(y: f64, size: f64, n: u32) -> TriangleSurface {
    let step = size / n as f64;
    let vertices = (0..=n)
        .flat_map(|j| {
            (0..=n).map(move |i| DVec3::new(i as f64 * step - size / 2.0, y, j as f64 * step - size / 2.0))
        })
        .collect();
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let triangles = (0..n)
        .flat_map(|j| {
            (0..n).flat_map(move |i| {
                [[at(i, j), at(i, j + 1), at(i + 1, j)], [at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)]]
            })
        })
        .collect();
    TriangleSurface { vertices, triangles }
}

/// The height of the bumpy sheet of [`bumpy_sheet`] over `(x, z)`.
fn bump_height(x: f64, z: f64) -> f64 {
    0.05 * (7.0 * x).sin() * (5.0 * z).cos()
}

/// A 2 m sheet of `2 n²` triangles raised into bumps: no two neighbouring triangles in a plane.
fn bumpy_sheet(n: u32) -> TriangleSurface {
    let mut bumpy = sheet(0.0, 2.0, n);
    for v in &mut bumpy.vertices {
        v.y = bump_height(v.x, v.z);
    }
    bumpy
}

/// Whether a contact found with the kept triangles is the one the whole hierarchy finds: equal
/// but for rounding, since at an edge the two triangles give its point each its own way.
fn same_contact(with_kept: Option<Surface<f64>>, walked: Option<Surface<f64>>) -> bool {
    match (with_kept, walked) {
        (Some(a), Some(b)) => (a.point - b.point).length() < 1e-12 && (a.normal - b.normal).length() < 1e-12,
        (a, b) => a == b,
    }
}

fn mesh(surface: TriangleSurface, thickness: f64, friction: f64, restitution: f64) -> Collider {
    Collider {
        shape: Shape::Mesh { surface: Arc::new(surface), thickness },
        friction,
        restitution,
        motion: None,
    }
}

fn particle(position: DVec3, velocity: DVec3) -> Model {
    let mut m = Model::default();
    m.add_particles([position], |_| 1.0, velocity);
    m
}

/// A deterministic sequence in [-1, 1).
fn uniform(seed: &mut u64) -> f64 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

fn corners(surface: &TriangleSurface) -> Vec<[Vec3<f64>; 3]> {
    surface.triangles.iter().map(|t| t.map(|i| Vec3::from_dvec3(surface.vertices[i as usize]))).collect()
}

#[test]
fn the_nearest_point_of_a_triangle_is_nearer_than_any_sampled_point_of_it() {
    let tri = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.2, 1.0, 0.3)];
    let mut seed = 7;
    for _ in 0..500 {
        let p = Vec3::new(uniform(&mut seed), uniform(&mut seed), uniform(&mut seed)) * 2.0;
        let (q, _) = triangle::nearest_point(tri, p);
        let found = (p - q).length();
        for i in 0..=40 {
            for j in 0..=40 - i {
                let (u, v) = (i as f64 / 40.0, j as f64 / 40.0);
                let sample = tri[0] + (tri[1] - tri[0]) * u + (tri[2] - tri[0]) * v;
                assert!(found <= (p - sample).length() + 1e-12, "{p:?}: {q:?} is not nearest");
            }
        }
    }
    // The features: a point straight above the face, beyond an edge, beyond a corner.
    assert_eq!(triangle::nearest_point(tri, Vec3::new(0.4, 0.3, 1.0)).1, Feature::Face);
    assert_eq!(triangle::nearest_point(tri, Vec3::new(0.5, -1.0, 0.0)).1, Feature::Edge(0));
    assert_eq!(triangle::nearest_point(tri, Vec3::new(-1.0, -1.0, 0.0)), (tri[0], Feature::Vertex(0)));
}

#[test]
fn a_segment_crosses_a_triangle_where_it_meets_its_plane() {
    let tri = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0)];
    let crossing = |start: Vec3<f64>, end: Vec3<f64>| triangle::crossing(tri, start, end - start);
    assert_eq!(crossing(Vec3::new(0.2, 1.0, 0.2), Vec3::new(0.2, -3.0, 0.2)), Some(0.25));
    assert_eq!(crossing(Vec3::new(0.2, -1.0, 0.2), Vec3::new(0.2, 1.0, 0.2)), Some(0.5));
    // Short of it, beside it, and within its plane.
    assert_eq!(crossing(Vec3::new(0.2, 1.0, 0.2), Vec3::new(0.2, 0.5, 0.2)), None);
    assert_eq!(crossing(Vec3::new(0.8, 1.0, 0.8), Vec3::new(0.8, -1.0, 0.8)), None);
    assert_eq!(crossing(Vec3::new(-1.0, 0.0, 0.2), Vec3::new(2.0, 0.0, 0.2)), None);
}

#[test]
fn the_hierarchy_finds_what_a_search_of_every_triangle_finds() {
    let sphere = icosphere(DVec3::new(0.1, -0.2, 0.3), 0.7, 3);
    let corners = corners(&sphere);
    let bvh = TriangleBvh::new(&corners);
    assert_eq!(bvh.len(), 1280);
    let mut seed = 11;
    let mut point = || Vec3::new(uniform(&mut seed), uniform(&mut seed), uniform(&mut seed)) * 1.5;
    for _ in 0..300 {
        let p = point();
        let brute = corners
            .iter()
            .map(|&tri| (p - triangle::nearest_point(tri, p).0).length_squared())
            .fold(f64::INFINITY, f64::min);
        let found = bvh.nearest(p, f64::INFINITY).unwrap();
        // Equal but for rounding: the planes of a triangle answer a point over its face.
        assert!((found.distance_squared - brute).abs() <= 1e-12 * brute, "{p:?}: {found:?} against {brute}");
        // A radius short of the nearest distance finds nothing.
        assert!(bvh.nearest(p, 0.999 * brute.sqrt()).is_none());

        let (start, end) = (p, point());
        let brute = corners
            .iter()
            .enumerate()
            .filter_map(|(t, &tri)| triangle::crossing(tri, start, end - start).map(|s| (t, s)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let found = bvh.first_crossing(start, end, |_, _| true);
        assert_eq!(found.map(|f| f.1), brute.map(|b| b.1), "{start:?} to {end:?}");
    }
}

#[test]
fn the_triangles_within_a_radius_are_those_a_search_of_every_triangle_finds() {
    let sphere = icosphere(DVec3::new(0.1, -0.2, 0.3), 0.7, 3);
    let corners = corners(&sphere);
    let bvh = TriangleBvh::new(&corners);
    let mut seed = 5;
    let mut point = || Vec3::new(uniform(&mut seed), uniform(&mut seed), uniform(&mut seed)) * 1.2;
    let mut total = 0;
    for _ in 0..200 {
        let p = point();
        let radius = 0.2;
        let brute: Vec<usize> = (0..corners.len())
            .filter(|&t| (p - triangle::nearest_point(corners[t], p).0).length_squared() <= radius * radius)
            .collect();
        let mut slots = Vec::new();
        assert!(bvh.within(p, radius, |slot| {
            slots.push(slot);
            true
        }));
        // Slots are in leaf order: the nearest among them names the triangle in the given order.
        let mut found: Vec<usize> =
            slots.iter().map(|&s| bvh.nearest_among(&[s], p, radius).unwrap().triangle).collect();
        found.sort_unstable();
        assert_eq!(found, brute, "{p:?}");
        total += brute.len();
        // A visit that says stop ends the walk.
        let mut visits = 0;
        let all = bvh.within(p, radius, |_| {
            visits += 1;
            visits < 2
        });
        assert_eq!((all, visits), (brute.len() < 2, brute.len().min(2)));
    }
    assert!(total > 200, "the points meet {total} triangles in all");
}

/// Follows particles from `start` on random paths that `drift` pulls onto `surface`, mostly in
/// short steps and now and then a long one, and checks that each step's contact found among the
/// triangles kept near the particle is the contact the hierarchy finds (within rounding). Returns the share of steps
/// that took the kept triangles with some triangle among them.
fn kept_triangles_give_the_hierarchys_contacts(
    surface: &TriangleSurface,
    thickness: f64,
    start: fn(&mut u64) -> Vec3<f64>,
    drift: fn(Vec3<f64>) -> Vec3<f64>,
) -> f64 {
    let shape = mesh::MeshShape::<f64>::new(surface, thickness);
    let particles = 64;
    let mut nearby = nearby_triangles::NearbyTriangles::new(particles);
    let mut nearby = nearby.band();
    let mut seed = 7;
    let mut kept_steps = 0;
    let steps = 300;
    for p in 0..particles {
        let mut x = start(&mut seed);
        for step in 0..steps {
            let reach = if step % 29 == 0 { 0.3 } else { 0.2 * thickness };
            let jitter = Vec3::new(uniform(&mut seed), uniform(&mut seed), uniform(&mut seed)) * reach;
            let end = x + jitter + drift(x) * thickness;
            let mut slots = [0; nearby_triangles::CAPACITY];
            let keep = thickness * nearby_triangles::KEEP;
            let kept = nearby.kept(p, x, end, keep, &mut slots);
            kept_steps += usize::from(kept.is_some_and(|k| k.count > 0));
            let with_kept = shape.contact(x, end, Some((&mut nearby, p)));
            let walked = shape.contact(x, end, None);
            assert!(
                same_contact(with_kept, walked),
                "particle {p}, step {step}: {x:?} to {end:?}: {with_kept:?} against {walked:?}"
            );
            x = walked.map_or(end, |s| s.point);
        }
    }
    kept_steps as f64 / (particles * steps) as f64
}

#[test]
fn the_triangles_kept_near_a_particle_give_the_contacts_the_hierarchy_gives() {
    let thickness = 0.02;
    // A closed mesh (a solid), particles falling towards its centre from around it.
    let sphere = icosphere(DVec3::ZERO, 0.5, 3);
    let around = |seed: &mut u64| {
        let v = Vec3::new(uniform(seed), uniform(seed), uniform(seed));
        v * (0.6 / v.length().max(1e-3))
    };
    let inwards = |x: Vec3<f64>| x * -0.2;
    let share = kept_triangles_give_the_hierarchys_contacts(&sphere, thickness, around, inwards);
    assert!(share > 0.2, "only {share} of the steps on the sphere kept their triangles");
    // A bumpy open sheet, particles falling onto it from above.
    let bumpy = bumpy_sheet(24);
    let above = |seed: &mut u64| Vec3::new(0.8 * uniform(seed), 0.1, 0.8 * uniform(seed));
    let down = |_: Vec3<f64>| Vec3::new(0.0, -0.2, 0.0);
    let share = kept_triangles_give_the_hierarchys_contacts(&bumpy, thickness, above, down);
    assert!(share > 0.2, "only {share} of the steps on the sheet kept their triangles");
}

#[test]
fn a_particle_resting_on_a_mesh_meets_only_its_nearest_triangle_and_crosses_none() {
    // Particles resting on a bumpy sheet, sinking a little each step and put back, as a cloth
    // lying on a mesh is: after the first step each meets one kept triangle and tests no
    // crossing, and its contact is still the one the whole hierarchy gives.
    let thickness = 0.02;
    let bumpy = bumpy_sheet(24);
    let shape = mesh::MeshShape::<f64>::new(&bumpy, thickness);
    let (particles, steps) = (64, 50);
    let mut nearby = nearby_triangles::NearbyTriangles::new(particles);
    let mut nearby = nearby.band();
    let mut seed = 3;
    let (mut alone, mut touching) = (0, 0);
    for p in 0..particles {
        let (x, z) = (0.8 * uniform(&mut seed), 0.8 * uniform(&mut seed));
        let over = Vec3::new(x, bump_height(x, z) + 0.5 * thickness, z);
        let mut x = shape.inside(over).unwrap().point;
        for step in 0..steps {
            let slide = Vec3::new(uniform(&mut seed), 0.0, uniform(&mut seed)) * 1e-6;
            let end = x + slide - Vec3::new(0.0, 1e-4 * thickness, 0.0);
            let mut slots = [0; nearby_triangles::CAPACITY];
            let kept = nearby.kept(p, x, end, thickness * nearby_triangles::KEEP, &mut slots);
            alone +=
                usize::from(kept == Some(nearby_triangles::Kept { count: 1, clear: true, over_face: true }));
            let with_kept = shape.contact(x, end, Some((&mut nearby, p)));
            let walked = shape.contact(x, end, None);
            assert!(
                same_contact(with_kept, walked),
                "particle {p}, step {step}: {with_kept:?} against {walked:?}"
            );
            touching += usize::from(walked.is_some());
            x = walked.map_or(end, |s| s.point);
        }
    }
    let share = alone as f64 / (particles * (steps - 1)) as f64;
    // The others rest over a ridge's edge or corner, where two triangles are about as near
    // (0.87 of the steps met one triangle alone when this was written).
    assert!(share > 0.8, "only {share} of the resting steps met one triangle alone");
    assert_eq!(touching, particles * steps, "every step sinks into the sheet");
}

#[test]
fn closed_meshes_are_told_from_open_ones_and_turned_outwards() {
    let sphere = icosphere(DVec3::ZERO, 1.0, 1);
    assert!(sphere.is_closed());
    assert!(!sheet(0.0, 1.0, 4).is_closed());
    let mut holed = sphere.clone();
    holed.triangles.pop();
    assert!(!holed.is_closed());
    // Inconsistent winding: one triangle flipped.
    let mut flipped = sphere.clone();
    flipped.triangles[0].swap(1, 2);
    assert!(!flipped.is_closed());
    // Wound inwards: still closed, and the centre is still inside.
    let mut inwards = sphere.clone();
    inwards.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    for surface in [sphere, inwards] {
        let shape = Shape::Mesh { surface: Arc::new(surface), thickness: 0.01 };
        assert!(shape.signed_distance(DVec3::ZERO) < -0.9);
        assert!(shape.signed_distance(DVec3::new(0.0, 2.0, 0.0)) > 0.9);
    }
    // Vertices repeated at one position are one vertex: a sphere split along every triangle.
    let whole = icosphere(DVec3::ZERO, 1.0, 1);
    let split = TriangleSurface {
        vertices: whole.triangles.iter().flat_map(|t| t.map(|i| whole.vertices[i as usize])).collect(),
        triangles: (0..whole.triangles.len() as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect(),
    };
    assert!(split.is_closed());
}

/// A closed cube of side 1 centred at the origin, its triangles facing out.
pub(super) fn unit_cube() -> TriangleSurface {
    TriangleSurface {
        vertices: (0..8)
            .map(|i| {
                DVec3::new((i & 1) as f64 - 0.5, ((i >> 1) & 1) as f64 - 0.5, ((i >> 2) & 1) as f64 - 0.5)
            })
            .collect(),
        triangles: vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ],
    }
}

#[test]
fn the_inside_of_a_closed_mesh_is_exact_at_faces_edges_and_corners() {
    // A cube's corners and edges are where a face normal alone misjudges the side.
    let cube = unit_cube();
    assert!(cube.is_closed());
    let shape = Shape::Mesh { surface: Arc::new(cube), thickness: 0.01 };
    let box_shape = Shape::Box { center: DVec3::ZERO, half_extents: DVec3::splat(0.5) };
    let mut seed = 3;
    for _ in 0..2000 {
        let p = DVec3::new(uniform(&mut seed), uniform(&mut seed), uniform(&mut seed)) * 0.9;
        let (mesh, exact) = (shape.signed_distance(p), box_shape.signed_distance(p));
        assert!((mesh - exact).abs() < 1e-12, "{p:?}: mesh {mesh}, box {exact}");
    }
}

fn still(dt: f64, colliders: Vec<Collider>) -> Config {
    Config { integrator: IntegratorKind::SymplecticEuler, dt, colliders, ..Config::default() }
}

#[test]
fn a_particle_at_100_m_s_stops_at_a_thin_sheet_from_either_side() {
    let dt = 1.0 / 60.0;
    let thickness = 0.005;
    for integrator in [
        IntegratorKind::SymplecticEuler,
        IntegratorKind::Verlet,
        IntegratorKind::Rk4,
        IntegratorKind::ImplicitEuler,
    ] {
        for (start, velocity) in [(1.0, -100.0), (-1.0, 100.0)] {
            // Aimed at a shared edge and at a corner of the sheet's triangles as well as inside one.
            for x in [0.013, 0.0, 0.125] {
                let model = particle(DVec3::new(x, start, x), DVec3::new(0.0, velocity, 0.0));
                let colliders = vec![mesh(sheet(0.0, 2.0, 8), thickness, 0.3, 0.0)];
                let config = Config { integrator, gravity: DVec3::ZERO, ..still(dt, colliders) };
                let mut sim = Simulation::<f64>::new(&model, &config);
                sim.step().unwrap();
                let y = sim.state().positions.get(0).y;
                let expected = thickness * start.signum();
                assert!((y - expected).abs() < 1e-12, "{integrator:?} from {start}: at {y}");
                assert!(sim.state().velocities.get(0).y.abs() < 1e-12);
            }
        }
    }
}

#[test]
fn a_particle_inside_a_closed_mesh_goes_out_to_its_nearest_surface() {
    let sphere = icosphere(DVec3::ZERO, 1.0, 3);
    let thickness = 0.01;
    let model = particle(DVec3::new(0.0, 0.0, 0.6), DVec3::ZERO);
    let sim = Simulation::<f64>::new(&model, &still(1e-3, vec![mesh(sphere.clone(), thickness, 0.3, 0.0)]));
    let x = sim.state().positions.get(0).to_dvec3();
    // Out through the nearest face: about 0.4 m out along +z, less the chord error of the
    // icosphere (below 0.5 % of the radius at three levels).
    assert!(x.z > 0.99, "{x:?}");
    let moved = (x - DVec3::new(0.0, 0.0, 0.6)).length();
    assert!(moved <= 0.4 + thickness + 1e-12 && moved > 0.4 + thickness - 0.005, "{x:?}");
    let shape = Shape::Mesh { surface: Arc::new(sphere), thickness };
    assert!((shape.signed_distance(x) - thickness).abs() < 1e-12);
}

#[test]
fn a_dropped_particle_rebounds_from_a_mesh_floor_as_from_a_plane() {
    for e in [0.5, 0.8] {
        let run = |collider: Collider| {
            let model = particle(DVec3::new(0.1, 1.0, 0.2), DVec3::ZERO);
            let mut sim = Simulation::<f64>::new(&model, &still(1e-4, vec![collider]));
            let mut peak: f64 = 0.0;
            let mut bounced = false;
            for _ in 0..13_000 {
                sim.step().unwrap();
                let (x, v) = (sim.state().positions.get(0), sim.state().velocities.get(0));
                bounced |= v.y > 0.0;
                if bounced {
                    peak = peak.max(x.y);
                }
            }
            peak
        };
        let thickness = 0.01;
        let floor = run(mesh(sheet(-thickness, 4.0, 4), thickness, 0.3, e));
        let plane = run(Collider {
            shape: Shape::Plane { point: DVec3::ZERO, normal: DVec3::Y },
            friction: 0.3,
            restitution: e,
            motion: None,
        });
        assert!((floor - plane).abs() < 1e-9, "e {e}: mesh {floor}, plane {plane}");
        assert!((floor - e * e).abs() < 0.02 * e * e, "e {e}: peak {floor}");
    }
}

#[test]
fn sliding_on_a_mesh_stops_after_v_squared_over_two_mu_g() {
    let (mu, speed, g) = (0.4, 2.0, 9.81);
    let thickness = 0.01;
    let model = particle(DVec3::new(-1.0, 0.0, 0.1), DVec3::new(speed, 0.0, 0.0));
    let colliders = vec![mesh(sheet(-thickness, 4.0, 16), thickness, mu, 0.0)];
    let mut sim = Simulation::<f64>::new(&model, &still(1e-4, colliders));
    for _ in 0..20_000 {
        sim.step().unwrap();
    }
    let travelled = sim.state().positions.get(0).x + 1.0;
    let expected = speed * speed / (2.0 * mu * g);
    assert!((travelled - expected).abs() < 0.01 * expected, "travelled {travelled}, expected {expected}");
    assert!(sim.state().velocities.get(0).length() < 1e-9);
    assert!(sim.state().positions.get(0).y.abs() < 1e-12);
}

#[test]
fn contacts_with_a_mesh_never_add_energy_nor_leave_a_particle_inside() {
    let sphere = icosphere(DVec3::new(0.1, 0.0, 0.0), 0.5, 2);
    let thickness = 0.02;
    for (friction, restitution) in [(0.0, 1.0), (0.3, 0.0), (2.0, 0.5)] {
        let collider = mesh(sphere.clone(), thickness, friction, restitution);
        let shape = collider.shape.clone();
        let mut seed = 5;
        let mut next = || uniform(&mut seed);
        let mut outside = || loop {
            let p = Vec3::new(next(), next(), next());
            if shape.signed_distance(p.to_dvec3()) >= thickness {
                return p;
            }
        };
        let start: Vectors<f64> = (0..1000).map(|_| outside()).collect();
        let mut seed = 17;
        let mut next = || uniform(&mut seed);
        let end: Vectors<f64> =
            start.iter().map(|p| Vec3::new(next(), next(), next()) * 0.8 + p * 0.5).collect();
        let velocities: Vectors<f64> = (0..1000).map(|_| Vec3::new(next(), next(), next()) * 3.0).collect();
        let mut contacts = Contacts::<f64>::new(&[collider], 1000).unwrap();
        contacts.begin_step(&start, &mut velocities.clone(), 1e-3);
        let mut state = State { positions: end, velocities: velocities.clone() };
        contacts.resolve(&mut state, &[1.0; 1000]);
        for p in 0..1000 {
            let (before, after) =
                (velocities.get(p).length_squared(), state.velocities.get(p).length_squared());
            assert!(after <= before * (1.0 + 1e-12), "{p} gained energy: {before} -> {after}");
            let distance = shape.signed_distance(state.positions.get(p).to_dvec3());
            assert!(distance > thickness - 1e-9, "particle {p} at {distance}, inside the thickness");
        }
    }
}

#[test]
fn single_precision_mesh_contacts_hold_as_well() {
    let dt = 1.0 / 60.0;
    let model = particle(DVec3::new(0.3, 1.0, -0.2), DVec3::new(0.0, -100.0, 0.0));
    let colliders = vec![mesh(icosphere(DVec3::new(0.0, -1.0, 0.0), 1.0, 2), 0.005, 0.3, 0.0)];
    let mut sim =
        Simulation::<f32>::new(&model, &Config { gravity: DVec3::ZERO, ..still(dt, colliders.clone()) });
    sim.step().unwrap();
    let x = sim.state().positions.get(0).to_dvec3();
    let distance = colliders[0].shape.signed_distance(x);
    assert!((distance - 0.005).abs() < 1e-5, "{x:?} at {distance}");
}

#[test]
fn a_mesh_is_a_stage_named_mesh_only_when_present() {
    let model = particle(DVec3::new(0.0, 1.0, 0.0), DVec3::ZERO);
    let none = Simulation::<f64>::new(&model, &still(1e-3, vec![]));
    assert!(!none.stages().contains(&"mesh"));
    let two = vec![mesh(sheet(0.0, 1.0, 2), 0.01, 0.3, 0.0), mesh(sheet(0.5, 1.0, 2), 0.01, 0.3, 0.0)];
    let with = Simulation::<f64>::new(&model, &still(1e-3, two));
    assert_eq!(with.stages(), ["gravity", "mesh"]);
}

#[test]
fn degenerate_triangles_are_left_out_and_never_make_a_nan() {
    let mut surface = sheet(0.0, 1.0, 2);
    // A triangle with a repeated corner and one with three corners in a line.
    surface.vertices.extend([
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(0.1, 0.0, 0.0),
        DVec3::new(0.2, 0.0, 0.0),
    ]);
    let n = surface.vertices.len() as u32;
    surface.triangles.extend([[n - 3, n - 3, n - 1], [n - 3, n - 2, n - 1]]);
    let collider = mesh(surface, 0.01, 0.3, 0.0);
    let model = particle(DVec3::new(0.1, 0.5, 0.0), DVec3::new(0.0, -50.0, 0.0));
    let mut sim =
        Simulation::<f64>::new(&model, &Config { gravity: DVec3::ZERO, ..still(0.05, vec![collider]) });
    sim.step().unwrap();
    let x = sim.state().positions.get(0).to_dvec3();
    assert!((x.y - 0.01).abs() < 1e-12, "{x:?}");
}

/// Resolves the one collider of `contacts` one particle at a time, as every particle was before
/// resting particles were answered a block at a time: the test `reaches`, then the exact contact.
fn resolve_one_by_one<T: Real>(contacts: &mut Contacts<T>, state: &mut State<T>, inverse_masses: &[T]) {
    let c = &contacts.colliders[0];
    let (ShapeIn::Mesh(mesh), Some(nearby)) = (&c.shape, &mut contacts.nearby[0]) else {
        panic!("a mesh collider")
    };
    let mut nearby = nearby.band();
    let n = inverse_masses.len();
    let [x, y, z] = state.positions.axes_mut();
    let [u, v, w] = state.velocities.axes_mut();
    let start = contacts.start.range(0..n);
    let h = contacts.step;
    let friction = contacts.friction.as_mut().map(|f| {
        let (given, next) = f.parts();
        given.band(0..n, next, h)
    });
    let mut band = Band { start, positions: [x, y, z], velocities: [u, v, w], inverse_masses, friction };
    for p in 0..n {
        let at = |axes: [&[T]; 3]| Vec3::new(axes[0][p], axes[1][p], axes[2][p]);
        if mesh.reaches(at(start), at(band.positions.each_ref().map(|a| &**a))) {
            band.contact(c, Some(&mut nearby), p);
        }
    }
    contacts.carry_on(state);
}

/// How many free particles that may touch the mesh [`mesh_lanes::resolve_blocks`] answers,
/// resolving the rest one at a time as the stage does: of all, of those in `marked`, and how many
/// of those in `marked` may touch it.
fn resolve_by_blocks<T: Real>(
    contacts: &mut Contacts<T>,
    state: &mut State<T>,
    inverse_masses: &[T],
    marked: &[bool],
) -> (usize, usize, usize) {
    let c = &contacts.colliders[0];
    let (ShapeIn::Mesh(mesh), Some(nearby)) = (&c.shape, &mut contacts.nearby[0]) else {
        panic!("a mesh collider")
    };
    let mut nearby = nearby.band();
    let n = inverse_masses.len();
    let [x, y, z] = state.positions.axes_mut();
    let [u, v, w] = state.velocities.axes_mut();
    let start = contacts.start.range(0..n);
    let h = contacts.step;
    let friction = contacts.friction.as_mut().map(|f| {
        let (given, next) = f.parts();
        given.band(0..n, next, h)
    });
    let mut band = Band { start, positions: [x, y, z], velocities: [u, v, w], inverse_masses, friction };
    let (mut answered, mut answered_marked, mut marked_candidates) = (0, 0, 0);
    for block in (0..n).step_by(LANES) {
        let mut rest = [0];
        mesh_lanes::resolve_blocks(mesh, &nearby, &mut band, block, &mut rest, c.friction, c.restitution);
        for lane in 0..LANES {
            let p = block + lane;
            let candidate = mesh.reaches(
                Vec3::new(start[0][p], start[1][p], start[2][p]),
                Vec3::new(band.positions[0][p], band.positions[1][p], band.positions[2][p]),
            );
            let free_candidate = candidate && inverse_masses[p] != T::ZERO;
            marked_candidates += usize::from(free_candidate && marked[p]);
            if (rest[0] >> lane) & 1 == 1 && candidate {
                band.contact(c, Some(&mut nearby), p);
            } else if free_candidate {
                answered += 1;
                answered_marked += usize::from(marked[p]);
            }
        }
    }
    contacts.carry_on(state);
    (answered, answered_marked, marked_candidates)
}

/// How particles resting on a sheet fared in [`stepped_three_ways`]: of the steps of free
/// particles, those the lanes answered, those of them that were marked, the steps of marked
/// particles that may touch the sheet, and the steps that pushed a particle; and how many free
/// particles were marked.
struct Shares {
    touching: usize,
    answered: usize,
    answered_marked: usize,
    marked: usize,
    pushed: usize,
    marked_particles: usize,
}

/// Particles resting on `surface` (of height `height` over `(x, z)`) where `place` puts them
/// (and marks some), stepped by the stage, by blocks in lanes and one at a time, with friction
/// carried from step to step: every step gives the same positions and velocities, exactly.
fn stepped_three_ways<T: Real>(
    surface: TriangleSurface,
    height: fn(f64, f64) -> f64,
    place: &dyn Fn(usize, &mut u64) -> (f64, f64, bool),
) -> Shares {
    let thickness = 0.02;
    let collider = mesh(surface, thickness, 0.4, 0.3);
    let particles = 1024;
    let mut seed = 11;
    let mut state = State { positions: Vectors::zeros(particles), velocities: Vectors::zeros(particles) };
    let mut marked = vec![false; particles];
    for (p, marked) in marked.iter_mut().enumerate() {
        let (x, z, mark) = place(p, &mut seed);
        *marked = mark;
        state.positions.set(p, Vec3::from_dvec3(DVec3::new(x, height(x, z) + 0.5 * thickness, z)));
        // Half slide (tangential speed beyond what friction takes), half stick; all approach.
        let tangential = if p % 2 == 0 { 1e-2 } else { 1e-5 };
        let velocity = DVec3::new(tangential * uniform(&mut seed), -1e-3, tangential * uniform(&mut seed));
        state.velocities.set(p, Vec3::from_dvec3(velocity));
    }
    let mut inverse_masses = vec![T::ONE; particles];
    inverse_masses[5] = T::ZERO;
    let stage =
        || Contacts::<T>::new(std::slice::from_ref(&collider), particles).unwrap().with_carried_friction();
    let (mut by_stage, mut one_by_one, mut by_blocks) = (stage(), stage(), stage());
    by_stage.project_out(&mut state.positions, &inverse_masses);
    let (mut a, mut b, mut d) = (state.clone(), state.clone(), state);
    let dt = T::from_f64(1e-5);
    let sink = Vec3::new(T::ZERO, T::from_f64(-1e-6 * thickness), T::ZERO);
    let (mut answered, mut answered_marked, mut marked_candidates, mut pushed) = (0, 0, 0, 0);
    let steps = 20;
    for step in 0..steps {
        for (contacts, state) in
            [(&mut by_stage, &mut a), (&mut one_by_one, &mut b), (&mut by_blocks, &mut d)]
        {
            contacts.begin_step(&state.positions, &mut state.velocities, dt);
            for p in (0..particles).filter(|&p| inverse_masses[p] != T::ZERO) {
                let moved = state.positions.get(p) + state.velocities.get(p) * dt + sink;
                state.positions.set(p, moved);
            }
        }
        by_stage.resolve(&mut a, &inverse_masses);
        let moved = b.positions.clone();
        resolve_one_by_one(&mut one_by_one, &mut b, &inverse_masses);
        pushed += (0..particles).filter(|&p| b.positions.get(p) != moved.get(p)).count();
        let (all, near_edges, candidates) =
            resolve_by_blocks(&mut by_blocks, &mut d, &inverse_masses, &marked);
        (answered, answered_marked) = (answered + all, answered_marked + near_edges);
        marked_candidates += candidates;
        for p in 0..particles {
            let [x, y, z] = [&a, &b, &d].map(|s| (s.positions.get(p), s.velocities.get(p)));
            assert!(x == y && y == z, "step {step}, particle {p}: {x:?}, {y:?} one by one, {z:?}");
        }
    }
    let free = |p: &usize| inverse_masses[*p] != T::ZERO;
    Shares {
        touching: (0..particles).filter(free).count() * steps,
        answered,
        answered_marked,
        marked: marked_candidates,
        pushed,
        marked_particles: (0..particles).filter(free).filter(|&p| marked[p]).count(),
    }
}

/// Particles resting on a bumpy sheet: the lanes answer most particles, also some a hundredth of
/// a thickness from a triangle's edge, and none wrongly at the sheet's border, where the nearest
/// point is on an edge with no triangle beyond.
fn lanes_give_the_one_particle_contacts<T: Real>() {
    let cells = 24;
    let step = 2.0 / cells as f64;
    let place = |p: usize, seed: &mut u64| {
        let (mut x, z) = (0.8 * uniform(seed), 0.8 * uniform(seed));
        // Every fourth particle over a line of edges (x = const), a little to one side.
        let marked = p.is_multiple_of(4);
        if marked {
            let offset = [1e-2, -1e-2, 1e-5, -1e-5][p / 4 % 4] * 0.02;
            x = ((x + 1.0) / step).round() * step - 1.0 + offset;
        }
        // And some at the sheet's border, over it or just beyond it.
        if p % 8 == 1 {
            x = 1.0 + 0.5 * 0.02 * uniform(seed);
        }
        (x, z, marked)
    };
    let shares = stepped_three_ways::<T>(bumpy_sheet(cells), bump_height, &place);
    let Shares { touching, answered, answered_marked, marked, pushed, .. } = shares;
    // The first step gathers every particle's triangles one at a time; a particle over a ridge,
    // a hundred-thousandth of a thickness from an edge, or at the border is left to the
    // one-particle path.
    assert!(answered as f64 > 0.6 * touching as f64, "lanes answered {answered} of {touching}");
    assert!(answered_marked as f64 > 0.3 * marked as f64, "near edges: {answered_marked} of {marked}");
    assert!(pushed as f64 > 0.6 * touching as f64, "{pushed} of {touching} contacts pushed a particle");
}

#[test]
fn a_block_of_resting_particles_in_lanes_meets_the_mesh_as_one_particle_at_a_time() {
    lanes_give_the_one_particle_contacts::<f64>();
    lanes_give_the_one_particle_contacts::<f32>();
}

/// Particles resting on a flat sheet exactly over its edges (lines along x, along z and along
/// the cells' diagonals, and corners), where two or more triangles of one plane are equally
/// near: the lanes answer them as over a face, with the one-particle contacts exactly; those at
/// the sheet's border, with no triangle beyond the edge, stay with the one-particle path.
fn lanes_answer_particles_over_edges_between_triangles_of_one_plane<T: Real>() {
    let cells = 24;
    let step = 2.0 / cells as f64;
    let line = |x: f64| ((x + 1.0) / step).round() * step - 1.0;
    let place = |p: usize, seed: &mut u64| {
        let (x, z) = (0.8 * uniform(seed), 0.8 * uniform(seed));
        // Exactly on a line, or a hundred-thousandth of a thickness to one side.
        let off = [0.0, 1e-5 * 0.02, -1e-5 * 0.02][p / 5 % 3];
        match p % 5 {
            0 => (line(x) + off, z, true),
            1 => (x, line(z) + off, true),
            // The diagonal of a cell runs along x + z = const, through its corners.
            2 => {
                let sum = line(x + z + 1.0) - 1.0 + off;
                (x, sum - x, true)
            }
            3 => (line(x), line(z), true),
            _ => (1.0 + off, z, false),
        }
    };
    let flat = |_: f64, _: f64| 0.0;
    let shares = stepped_three_ways::<T>(sheet(0.0, 2.0, cells), flat, &place);
    let Shares { touching, answered, answered_marked, marked, pushed, marked_particles } = shares;
    // Every step of a marked particle that may touch the sheet is answered in lanes, but its
    // first, which gathers its triangles. (In `f32` some rest a rounding above the thickness,
    // out of touch.)
    assert!(answered_marked + marked_particles >= marked, "over edges: {answered_marked} of {marked}");
    assert!(marked as f64 > 0.7 * (touching / 5 * 4) as f64, "{marked} steps over edges in touch");
    assert_eq!(answered, answered_marked, "particles at the border answered in lanes");
    assert!(pushed as f64 > 0.7 * touching as f64, "{pushed} of {touching} contacts pushed a particle");
}

#[test]
fn lanes_answer_particles_resting_over_edges_between_triangles_of_one_plane() {
    lanes_answer_particles_over_edges_between_triangles_of_one_plane::<f64>();
    lanes_answer_particles_over_edges_between_triangles_of_one_plane::<f32>();
}

/// Particles resting on the top of a solid ball (a closed mesh, whose planes the lanes keep
/// facing outward): the lanes answer most of them, with the one-particle contacts exactly.
fn lanes_give_the_one_particle_contacts_on_a_solid<T: Real>() {
    let ball = icosphere(DVec3::ZERO, 0.5, 3);
    assert!(ball.is_closed());
    let top = |x: f64, z: f64| (0.25 - x * x - z * z).sqrt();
    let place = |_: usize, seed: &mut u64| (0.3 * uniform(seed), 0.3 * uniform(seed), false);
    let Shares { touching, answered, .. } = stepped_three_ways::<T>(ball, top, &place);
    assert!(answered as f64 > 0.6 * touching as f64, "lanes answered {answered} of {touching}");
}

#[test]
fn a_block_of_particles_resting_on_a_solid_meets_it_in_lanes_as_one_particle_at_a_time() {
    lanes_give_the_one_particle_contacts_on_a_solid::<f64>();
    lanes_give_the_one_particle_contacts_on_a_solid::<f32>();
}
