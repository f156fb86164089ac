//! Point-based models of rigid objects: positions, normals, splat radii and
//! optional colours, loaded from PLY (or sampled from a mesh).
//!
//! Everything the splatter needs per point lives here. Units are the model's
//! own (the PLY's; metres for most scanners).
//!
//! How loading works ([`PointModel::load_with`]):
//! 1. the PLY is read by the `ply` codec (ascii, binary little- or
//!    big-endian; counts checked against the file size before any
//!    allocation) through the point-model `schema` (which properties are
//!    positions, normals, colours, radii);
//! 2. points with a NaN or infinite coordinate are dropped (counted in
//!    [`Provenance::dropped_non_finite`], with a warning);
//! 3. loaded radii must be finite and > 0, or the file is refused; loaded
//!    normals are normalised, and zero-length or non-finite ones are
//!    re-estimated (with a warning, counted in
//!    [`Provenance::normals_reestimated`]) and oriented to agree with their
//!    loaded neighbours;
//! 4. missing normals and radii are estimated from the k nearest neighbours
//!    (PCA normals oriented after Hoppe et al. 1992, radii from the local
//!    spacing): the `estimate` submodule's docs give the method and the
//!    choice of the radius factor.
//!
//! A PLY with faces loads as its vertices under [`PointModel::load`]; to sample
//! the surface instead, use [`load_mesh_ply`] and [`TriangleMesh::sample`], or
//! [`PointModel::load_auto`] with a point count. [`PointModel::load_any_with`]
//! (what the commands use) samples every mesh: OBJ, STL ([`load_stl`]) and
//! PLY with faces.

mod eigen;
mod error;
mod estimate;
mod gaps;
mod load;
mod merge;
mod mesh;
mod orient;
mod ply;
mod pointwise;
mod schema;
pub mod shapes;
mod stage;
mod stl;
mod types;

pub use error::ModelError;
pub use gaps::{GAP_MODEL_FRACTION, GAP_NEIGHBOURS, GapClosure};
pub use mesh::{DEFAULT_MESH_POINTS, MESH_RADIUS_FACTOR, TriangleMesh, load_mesh_ply, load_obj};
pub use stl::{load_stl, parse_stl};
pub use types::{AttributeSource, LoadOptions, PointModel, Provenance};
