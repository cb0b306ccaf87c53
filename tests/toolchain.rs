//! The declared minimum Rust version (`rust-version` in `Cargo.toml`) is
//! real: no dependency this machine builds asks for a newer compiler. Cargo
//! itself refuses a toolchain older than the declared version, so with this
//! check a newcomer's older compiler gets one clear message instead of a
//! dependency's build error.

use std::process::Command;

fn version(text: &str) -> Vec<u32> {
    text.split('.').map(|p| p.parse().unwrap_or(0)).collect()
}

#[test]
fn declared_rust_version_covers_every_dependency() {
    // The packages this machine builds: a fresh checkout has downloaded
    // only those (not the Android or Windows ones), and reads them offline.
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let verbose = Command::new(&rustc).arg("-vV").output().expect("rustc -vV");
    let verbose = String::from_utf8_lossy(&verbose.stdout);
    let host = verbose
        .lines()
        .find_map(|l| l.strip_prefix("host: "))
        .expect("rustc -vV names the host");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let output = Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--locked", "--offline"])
        .args(["--filter-platform", host])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run cargo metadata");
    assert!(
        output.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let metadata: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let packages = metadata["packages"].as_array().unwrap();
    let ours = packages
        .iter()
        .find(|p| p["name"] == "skyrender")
        .and_then(|p| p["rust_version"].as_str())
        .expect("Cargo.toml declares rust-version");
    let newer: Vec<String> = packages
        .iter()
        .filter_map(|p| {
            let needs = p["rust_version"].as_str()?;
            (version(needs) > version(ours))
                .then(|| format!("{} {} needs {needs}", p["name"], p["version"]))
        })
        .collect();
    assert!(
        newer.is_empty(),
        "rust-version = \"{ours}\" in Cargo.toml, but: {}",
        newer.join("; ")
    );
    // The compiler running the tests is at least the declared minimum
    // (cargo would have refused to build otherwise; checked here so the
    // declaration cannot silently drift above what CI runs).
    let rustc = Command::new(std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into()))
        .arg("--version")
        .output()
        .expect("rustc --version");
    let text = String::from_utf8_lossy(&rustc.stdout);
    let running = text.split_whitespace().nth(1).expect("rustc X.Y.Z");
    assert!(
        version(running) >= version(ours),
        "{text} is older than {ours}"
    );
}
