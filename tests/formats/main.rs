//! Each result format read back by a reader that is not ours, and checked against the JSON
//! result of the same run, number for number.

#[path = "../common/mod.rs"]
mod api;
mod colliders;
mod common;
#[path = "../deadline/mod.rs"]
mod deadline;
mod glb;
mod non_finite;
mod npy;
mod obj;
mod pc2;
mod selection;
