//! The Slurm example (`examples/slurm/`) end to end on a real cluster: a
//! 4-task job array of tiles plus the dependent merge, compared with a
//! single render; and a 3-frame timelapse array. Runs where a cluster
//! answers (`sinfo`); CI starts a one-node cluster on localhost
//! (`.ci/slurm-up`) and sets `SKYRENDER_REQUIRE_SLURM=1`, which turns a
//! missing cluster into a failure instead of a skip.

use std::path::{Path, PathBuf};
use std::process::Command;

fn cluster() -> bool {
    let up = Command::new("sinfo")
        .arg("-h")
        .output()
        .is_ok_and(|o| o.status.success() && !o.stdout.is_empty());
    if !up {
        assert!(
            std::env::var_os("SKYRENDER_REQUIRE_SLURM").is_none(),
            "SKYRENDER_REQUIRE_SLURM is set but no Slurm cluster answers (run .ci/slurm-up)"
        );
        eprintln!("skipped: no Slurm cluster answers `sinfo` (CI starts one with .ci/slurm-up)");
    }
    up
}

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("examples/slurm")
        .join(name)
}

fn run_script(script: &str, env: &[(&str, &str)]) {
    let out = Command::new(example(script))
        .envs(env.iter().copied())
        .env("SKYRENDER", env!("CARGO_BIN_EXE_skyrender"))
        .env("WAIT", "1")
        .output()
        .expect("run the example");
    assert!(
        out.status.success(),
        "{script}: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_tiled_render_on_slurm_merges_into_the_single_render() {
    if !cluster() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("parts");
    let scene = "--preset sunset --width 32 --height 16 --spp 2 --no-adaptive";
    run_script(
        "submit-tiles.sh",
        &[
            ("SCENE_ARGS", scene),
            ("TILES", "4"),
            ("OUT_DIR", out_dir.to_str().unwrap()),
        ],
    );
    for i in 0..4 {
        assert!(out_dir.join(format!("part_{i:04}.exr")).exists());
    }
    let single = dir.path().join("single.exr");
    let status = Command::new(env!("CARGO_BIN_EXE_skyrender"))
        .arg("render")
        .args(scene.split(' '))
        .arg("-o")
        .arg(&single)
        .status()
        .unwrap();
    assert!(status.success());
    assert!(
        std::fs::read(&single).unwrap() == std::fs::read(out_dir.join("sky.exr")).unwrap(),
        "the merged image differs from the single render"
    );
}

#[test]
fn a_timelapse_on_slurm_writes_one_frame_per_task() {
    if !cluster() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    run_script(
        "submit-timelapse.sh",
        &[
            (
                "SCENE_ARGS",
                "--lat 42.4434 --lon -76.4816 --width 16 --height 8 --spp 1",
            ),
            ("TIME_START", "2013-05-27T06:00:00-04:00"),
            ("TIME_END", "2013-05-27T18:00:00-04:00"),
            ("FRAMES", "3"),
            ("OUT_DIR", dir.path().to_str().unwrap()),
        ],
    );
    for frame in 1..=3 {
        assert!(dir.path().join(format!("sky_{frame:04}.exr")).exists());
    }
}
