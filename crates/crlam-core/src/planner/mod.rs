//! The IIG planner (Ghaffari Jadidi et al., IJRR 2019) as planner-spec 3 restates it: a
//! rapidly-exploring information-gathering tree whose nodes are scored by any
//! [`InformationFunction`](crate::info::InformationFunction), stopped when the relative
//! information contribution (RIC) converges.
//!
//! - [`settings`]: [`IigSettings`] with the reference-parity and clean presets and one switch per
//!   reference quirk (steer, collision walk, information accumulation, map mutation, nearest).
//! - [`world`]: [`PlannerWorld`], the prior lattice (SampleFree) and obstacle points
//!   (NoCollision).
//! - [`primitives`]: Steer, the collision walks, EdgeCost, SampleFree.
//! - [`spatial`]: the incremental bucket-grid index behind Nearest, Near and NoCollision.
//! - [`iig`]: [`run_iig`], the main loop, and its result types.
//! - [`paths`]: main-path voting and the most informative path, usable on hand-made trees.
//! - [`mod@geodesic`]: 8-connected Dijkstra distances on a traversable grid (the exploration loop's
//!   path search).

pub mod geodesic;
pub mod iig;
pub mod paths;
pub mod primitives;
pub mod settings;
pub mod spatial;
pub mod world;

pub use geodesic::{geodesic, Geodesic};
pub use iig::{run_iig, IigNode, IigResult, StopReason};
pub use paths::{
    candidate_paths, children_lists, dfs_leaves, main_paths, max_info_path, path_gain, root_path,
    vote_paths,
};
pub use settings::{
    CollisionMode, IigSettings, InfoAccumulation, MapMutation, NearestMode, SteerMode,
};
pub use world::PlannerWorld;
