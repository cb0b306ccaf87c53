//! # skyrender
//!
//! A physically based, spectral, Monte Carlo renderer of Earth's clear sky:
//! the U.S. Standard Atmosphere 1976 with Rayleigh scattering after Bucholtz
//! (1995), temperature-dependent ozone absorption, Elterman aerosols, a
//! Lambertian ground and the measured solar spectrum, rendered by unbiased
//! spectral path tracing with delta tracking and next-event estimation.
//!
//! Data flows one way: [`Scene`] → [`atmosphere::Atmosphere`] (physics) →
//! [`render::Renderer`] (integrator, camera, film) → [`output`] (EXR/PNG).
//!
//! ```
//! use skyrender::{Scene, render::Renderer};
//!
//! let mut scene = Scene::preset("midday").unwrap();
//! scene.render.width = 8;
//! scene.render.height = 4;
//! scene.render.spp = 2;
//! let renderer = Renderer::new(&scene).unwrap();
//! let mut film = renderer.new_film();
//! for pass in 0..scene.render.spp {
//!     renderer.render_pass(&mut film, pass, &|| false);
//! }
//! let image = film.to_rgb(); // linear Rec.709, Y in cd/m²
//! assert!(image.pixels[0][2] > 0.0); // the zenith row is lit
//! ```

#![warn(missing_docs)]

pub mod app;
pub mod atmosphere;
pub mod bench;
pub mod cli;
pub mod data;
pub mod error;
pub mod export;
pub mod lighting;
pub mod output;
pub mod physics;
pub mod plan;
pub mod render;
pub mod rng;
pub mod scene;
pub mod spectrum;

pub use scene::Scene;
