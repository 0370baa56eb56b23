//! The reference against external ground: stored images and other implementations, one test
//! binary (CPU only).
//! - [`goldens`]: the reference against the golden images in `goldens/`;
//! - [`azimuths`]: issue 30's azimuth views: the drawn layers, the rotation property, the limits;
//! - [`baselines`]: the reference baselines (Vegetation, Primitive) see the same trees as ours;
//! - [`embree_crosscheck`]: obvhs, behind the ground truth, agrees with Embree (embreex);
//! - [`shading`]: sun-depth shading (G§5) on lone trees: the seed's defect and its fix.
//! - [`blend`]: issue 30's G§4 blend per tree (one t per tree, covered pixels, kept fractions,
//!   translation invariance of the kept texels).
//! - [`hull`]: issue 32's batch hull (E§7): conservative, closed, convex, within budget.
//!
//! Run one module with `cargo test -p forestlod-tests --test reference <module>::`.

mod alternatives;
mod azimuths;
mod baselines;
mod blend;
mod embree_crosscheck;
mod far_bake;
mod goldens;
mod hull;
mod metric;
mod octahedral;
mod shading;
mod subsets;
