//! Exact closest-point and signed-distance queries on triangle surfaces, shared by the
//! mesher (`SurfaceDomain`) and surface scoring (`meshdev`).
//!
//! * [`Bvh`]: our own SAH bounding-volume hierarchy (`bvh`) returning the exact closest
//!   point (`closest`, Ericson's region method) and the feature it lies on.
//! * [`Pseudonormals`]: the inside/outside sign from angle-weighted pseudonormals
//!   (`pseudonormal`, Bærentzen & Aanæs 2005).
//! * [`SignedSurface`]: both together (`signed`); positive = outside.
//!
//! Closest-point engine: our own BVH, not `parry3d-f64` 0.31. Measured with a throwaway
//! probe on this 2-core machine while other builds ran (load average ≈ 10), 100,000-triangle
//! torus, 200,000 queries (90 % near the surface, 10 % up to 10 mm away), one thread, thread
//! CPU time per query: ours 2.05–2.25 µs, parry 3.55–4.30 µs (wall 3.9–5.9 µs against
//! 7.3–10.8 µs); build wall 120–170 ms against 195–280 ms; distances equal to 3.6e-15 mm.
//! Ours also returns the hit feature the pseudonormal sign needs, and adds no dependency
//! (parry 0.31 brings glam/glamx).

pub mod bvh;
pub mod closest;
pub mod error;
pub mod pseudonormal;
pub mod signed;

pub use bvh::{Bvh, ClosestHit};
pub use closest::{Feature, closest_point_on_triangle};
pub use error::{SpatialError, validate_mesh};
pub use pseudonormal::Pseudonormals;
pub use signed::SignedSurface;
