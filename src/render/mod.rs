//! Rendering: a [`Renderer`] turns a validated [`crate::Scene`] into samples on a
//! [`Film`], one pass at a time, in parallel over rows with rayon.
//!
//! Determinism: every pixel sample draws from its own generator seeded by
//! (scene seed, the pixel's sample number, pixel), each pixel sums its
//! samples in order, and the adaptive plan is a function of the image, so
//! the image does not depend on the number of threads. The splatted paths
//! ([`circles`], [`ground_circles`]) each draw from a generator of their
//! own, and their splats are added in the paths' order.

pub mod adaptive;
pub mod alloc;
pub mod camera;
pub mod circle_geometry;
pub mod circle_points;
pub mod circles;
pub mod columns;
pub mod control;
pub mod debias;
pub mod denoise;
pub mod directions;
pub mod exact;
pub mod fast;
pub mod film;
mod film_halves;
pub mod film_layers;
pub mod film_spectral;
pub mod ground_circles;
pub mod ground_sky;
pub mod guide;
pub mod integrator;
pub mod lane_values;
pub mod lanes;
pub mod layers;
pub mod medium;
pub mod memory;
pub mod noise_estimate;
pub mod observer_depths;
pub mod parts;
pub mod preview;
pub mod probe;
pub mod renderer;
pub mod service;
pub mod sky_model;
pub mod splatting;
pub mod sun_columns;
pub mod sunlight;
pub mod tables;
pub mod tracker;
pub mod transmittance;
pub mod trig;

pub use crate::plan::{IntegratorOptions, Sampler, TechniquePlan};
pub use camera::{direction_from_az_el, Camera, HalfMirror, Mirror, MirrorAxis};
pub use film::Film;
pub use integrator::Integrator;
pub use lanes::{LaneTable, SolarSource};
pub use medium::{Lanes, Medium, SpectralLanes, TransmittanceEstimator, LANES};
pub use memory::OutOfMemory;
pub use probe::SpectralEstimate;
pub use renderer::{
    mirror_halves, mirror_pairs, solar_source, PassStats, Renderer, ADAPTIVE_FROM_PASS,
};
