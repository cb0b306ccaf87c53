//! Writes `data/mars_dust_phase_mie.csv`: the Martian dust's phase function
//! at 360–840 nm by Lorenz–Mie theory (`physics::planet::mars_dust`), with
//! each wavelength's extinction efficiency, single-scattering albedo and
//! asymmetry parameter on stderr (quoted in `data/README.md`).
//!
//! `cargo run --release --example mars_dust_phase > data/mars_dust_phase_mie.csv`

use rayon::prelude::*;
use skyrender::physics::planet::mars_dust;

fn main() {
    let angles = mars_dust::table_angles_deg();
    let wavelengths: Vec<f64> = mars_dust::table_wavelengths_nm().collect();
    let blocks: Vec<_> = wavelengths
        .par_iter()
        .map(|&w| (w, mars_dust::mie_phase(w, &angles)))
        .collect();
    println!("# Martian dust phase function, Lorenz-Mie spheres: gamma sizes r_eff 1.5 um,");
    println!("# v_eff 0.3; refractive index data/mars_dust_refractive_index_wolff.csv.");
    println!("# Made by `cargo run --release --example mars_dust_phase` (see data/README.md).");
    println!("angle_deg,phase,wavelength_nm");
    for (w, optics) in &blocks {
        eprintln!(
            "{w} nm: Q_ext {:.4}, single-scattering albedo {:.4}, g {:.4}",
            optics.q_ext, optics.single_scattering_albedo, optics.asymmetry
        );
        for (a, p) in angles.iter().zip(&optics.phase) {
            println!("{a},{p:.7e},{w}");
        }
    }
}
