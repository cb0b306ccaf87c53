//! Pinned images: the exact bits of small renders and radiance probes of
//! four presets at a fixed seed. Restructuring the renderer must not change
//! what it computes; a change here is either a bug or a deliberate change of
//! the order of random numbers, made in a commit of its own whose message
//! shows the estimator tests and a side-by-side benchmark.
//!
//! The hashes cover every technique the presets switch on: the draft pass,
//! camera-ray densities and branches, segment estimates and the sky guide
//! (sunset, twilight), the control variate (sunset), roulette and splitting
//! and splatting along circles, the air's and the ground's, with their
//! transmittance table (sunset, twilight), the ground's alone (midday),
//! the sky model's light as the ground's control (midday,
//! sunset, twilight), the sun's shadow rays by their table (all four), and
//! the view from orbit (space).

use skyrender::render::Renderer;
use skyrender::Scene;

/// FNV-1a over a stream of 32-bit words: a stable hash (the standard
/// library's `DefaultHasher` may change between Rust releases).
fn fnv1a(words: impl IntoIterator<Item = u32>) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325_u64;
    for word in words {
        for byte in word.to_le_bytes() {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
    }
    hash
}

fn scene(preset: &str) -> Scene {
    let mut scene = Scene::preset(preset).unwrap();
    scene.render.width = 24;
    scene.render.height = 12;
    // The draft and two full passes: the adaptive plan reads the first.
    scene.render.spp = 3;
    scene.render.seed = 7;
    scene
}

fn image_hash(preset: &str) -> u64 {
    let scene = scene(preset);
    let renderer = Renderer::new(&scene).unwrap();
    let mut film = renderer.new_film();
    for pass in 0..scene.render.spp {
        assert!(renderer.render_pass(&mut film, pass, &|| false).completed);
    }
    fnv1a(
        film.to_rgb()
            .pixels
            .iter()
            .flat_map(|p| p.map(f32::to_bits)),
    )
}

fn probe_hash(preset: &str) -> u64 {
    let renderer = Renderer::new(&scene(preset)).unwrap();
    let estimates = renderer.probe_radiance(60.0, 30.0, &[450.0, 550.0, 650.0], 64);
    fnv1a(estimates.iter().flat_map(|e| {
        let radiance = e.radiance.to_bits();
        let error = e.std_error.to_bits();
        [
            radiance as u32,
            (radiance >> 32) as u32,
            error as u32,
            (error >> 32) as u32,
        ]
    }))
}

/// (preset, image hash, probe hash).
const PINS: [(&str, u64, u64); 4] = [
    ("midday", 0xa1e4dac4b383ed4d, 0xcdea56fd08a2ece6),
    ("sunset", 0x6c298e96aea95479, 0xad865225b08aa9b4),
    ("twilight", 0xe423ad644ad33a65, 0x412516a49174889e),
    ("space", 0xbc5a5d4f6b5b29ee, 0xa09d945a1cd8d6e5),
];

#[test]
fn the_pinned_images_and_probes_keep_their_bits() {
    let mut found = Vec::new();
    for (preset, _, _) in PINS {
        found.push((preset, image_hash(preset), probe_hash(preset)));
    }
    let text: Vec<String> = found
        .iter()
        .map(|(p, i, r)| format!("    (\"{p}\", {i:#018x}, {r:#018x}),"))
        .collect();
    assert_eq!(
        found,
        PINS.to_vec(),
        "the renders' bits changed; now:\n{}",
        text.join("\n")
    );
}
