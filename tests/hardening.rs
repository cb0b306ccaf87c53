//! The command line under stress: interrupted writes, memory limits,
//! unbounded input, and the messages a newcomer meets first.

mod common;

use common::{assert_one_line_error, skyrender, stderr};

use std::io::Write as _;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn kill(signal: &str, pid: u32) {
    let status = Command::new("kill")
        .args([&format!("-{signal}"), &pid.to_string()])
        .status()
        .expect("run kill");
    assert!(status.success(), "kill -{signal} {pid}");
}

/// Whether process `pid` has a file open in `dir` with data written to it
/// (its offset past 0): the output's write phase, not the check at start
/// that a file can be created there.
#[cfg(target_os = "linux")]
fn writing_into(pid: u32, dir: &Path) -> bool {
    let Ok(fds) = std::fs::read_dir(format!("/proc/{pid}/fd")) else {
        return false;
    };
    fds.flatten().any(|fd| {
        let into_dir = std::fs::read_link(fd.path()).is_ok_and(|target| target.starts_with(dir));
        let info = format!("/proc/{pid}/fdinfo/{}", fd.file_name().to_string_lossy());
        let written = std::fs::read_to_string(info).is_ok_and(|text| {
            text.lines()
                .find_map(|l| l.strip_prefix("pos:"))
                .and_then(|p| p.trim().parse::<u64>().ok())
                .is_some_and(|pos| pos > 0)
        });
        into_dir && written
    })
}

/// SIGINT, SIGTERM and SIGKILL in the middle of writing the output: the
/// previous file is intact and no temporary file is left. The process is
/// stopped (SIGSTOP) as soon as it has written part of its file, then sent
/// the signal and continued, so the signal lands inside the write phase
/// every time.
#[cfg(target_os = "linux")]
#[test]
fn a_signal_during_the_write_leaves_the_old_file_and_nothing_else() {
    for signal in ["INT", "TERM", "KILL"] {
        let dir = tempfile::tempdir().unwrap();
        let dir_path = dir.path().canonicalize().unwrap();
        let target = dir_path.join("sky.exr");
        std::fs::write(&target, b"the previous render").unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_skyrender"))
            .args(["render", "--preset", "midday", "--no-aerosols"])
            .args(["--width", "1024", "--height", "512", "--spp", "1", "-o"])
            .arg(&target)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let pid = child.id();
        let start = Instant::now();
        let mut caught = false;
        while start.elapsed() < Duration::from_mins(5) {
            if writing_into(pid, &dir_path) {
                kill("STOP", pid);
                caught = true;
                break;
            }
            if child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::sleep(Duration::from_micros(200));
        }
        assert!(caught, "SIG{signal}: never saw the write phase");
        kill(signal, pid);
        kill("CONT", pid);
        let status = child.wait().unwrap();
        assert!(!status.success(), "SIG{signal}: the render finished");
        assert_eq!(
            std::fs::read(&target).unwrap(),
            b"the previous render",
            "SIG{signal}: the old file changed"
        );
        assert_eq!(listing(&dir_path), ["sky.exr"], "SIG{signal}: left behind");
    }
}

/// The largest accepted image under a 1 GiB address-space limit: a one-line
/// error that says how much memory it needs, exit code 2, no file — not an
/// abort from a failed allocation.
#[cfg(unix)]
#[test]
fn a_render_too_large_for_the_memory_limit_stops_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("huge.exr");
    let command = format!(
        "ulimit -v 1048576 && exec '{}' render --preset sunset --width 16384 --height 8192 --spp 1 -o '{}'",
        env!("CARGO_BIN_EXE_skyrender"),
        target.display()
    );
    let out = Command::new("sh").args(["-c", &command]).output().unwrap();
    let err = assert_one_line_error(&out, &["not enough memory", "16384×8192", "GiB"]);
    // Sunset splats: film 37 bytes a pixel (exact XYZ sums 24, splats 12,
    // plan 1), then 19 for the plan's arrays: 56 × 2²⁷ bytes.
    assert!(err.contains("7.00 GiB"), "{err}");
    assert_eq!(listing(dir.path()), Vec::<String>::new());
}

#[test]
fn huge_numbers_are_shown_short() {
    let out = skyrender(&["atmosphere", "--sun-elevation", "1e308"]);
    let err = assert_one_line_error(&out, &["sun elevation", "1e308", "-90 to 90"]);
    assert!(err.len() < 120, "{err}");
    let out = skyrender(&["atmosphere", "--altitude", "-1e300"]);
    assert_one_line_error(&out, &["altitude", "-1e300"]);
}

#[test]
fn a_flag_without_its_value_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("out.exr");
    let out = skyrender(&["render", "--width", "-o", target.to_str().unwrap()]);
    assert_one_line_error(&out, &["--width", "value is required"]);
    assert!(!target.exists());
    // A negative number is still a value (and then out of range).
    let out = skyrender(&["render", "--width", "-5", "-o", target.to_str().unwrap()]);
    assert_one_line_error(&out, &["width", "-5", "1 to 65536"]);
    // So is a negative elevation.
    let out = skyrender(&["atmosphere", "--sun-elevation", "-4"]);
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn atmosphere_flags_without_their_constituent_are_noted() {
    for (args, note) in [
        (
            ["--no-aerosols", "--aerosol-amount", "5"],
            "--aerosol-amount",
        ),
        (["--no-ozone", "--ozone-du", "300"], "--ozone-du"),
    ] {
        let out = skyrender(&[&["atmosphere"], &args[..]].concat());
        assert!(out.status.success(), "{}", stderr(&out));
        let err = stderr(&out);
        assert!(
            err.starts_with("skyrender: note:") && err.contains(note) && err.contains("no effect"),
            "{args:?}: {err}"
        );
    }
    // Given with its constituent, no note.
    let out = skyrender(&["atmosphere", "--aerosol-amount", "5", "--ozone-du", "300"]);
    assert!(
        out.status.success() && stderr(&out).is_empty(),
        "{}",
        stderr(&out)
    );
}

#[test]
fn scene_files_name_the_bad_key_and_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("[[sun]]\nelevation_deg = 3.0\n", "`sun`"),
        ("[sun]\nelevation_deg = \"high\"\n", "`sun.elevation_deg`"),
        (
            "[camera]\nkind = \"equirect\"\n[camera.fov_deg]\n",
            "`camera.fov_deg`",
        ),
    ];
    for (i, (text, key)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad{i}.toml"));
        std::fs::write(&path, text).unwrap();
        let out = skyrender(&["atmosphere", "--scene", path.to_str().unwrap()]);
        assert_one_line_error(&out, &[key, "line"]);
    }
    // A file that is not a short text: refused at the cap, at once.
    let big = dir.path().join("big.toml");
    let mut file = std::fs::File::create(&big).unwrap();
    for _ in 0..1100 {
        file.write_all(&[b'#'; 1024]).unwrap();
    }
    drop(file);
    let out = skyrender(&["atmosphere", "--scene", big.to_str().unwrap()]);
    assert_one_line_error(&out, &["larger than 1024 KiB"]);
    let binary = dir.path().join("binary.toml");
    std::fs::write(&binary, [0x5b, 0xff, 0xfe, 0x00]).unwrap();
    let out = skyrender(&["atmosphere", "--scene", binary.to_str().unwrap()]);
    assert_one_line_error(&out, &["not UTF-8"]);
}

/// An endless input (`/dev/urandom`) is read up to the cap, not for ever.
#[cfg(unix)]
#[test]
fn an_endless_scene_file_is_refused_quickly() {
    let start = Instant::now();
    let out = skyrender(&["render", "--scene", "/dev/urandom", "-o", "never.exr"]);
    assert_one_line_error(&out, &["/dev/urandom", "larger than"]);
    assert!(start.elapsed() < Duration::from_secs(30));
    assert!(!Path::new("never.exr").exists());
}

/// Every flag of `render` says what it is; every value it takes says its
/// unit or range and its default (or is required).
#[test]
fn every_render_flag_has_a_help_line_with_its_default() {
    use clap::Subcommand;
    let cli = skyrender::cli::Command::augment_subcommands(clap::Command::new("skyrender"));
    let render = cli.find_subcommand("render").expect("render");
    for arg in render.get_arguments() {
        let id = arg.get_id().as_str();
        if id == "help" {
            continue;
        }
        let help = arg.get_help().map(ToString::to_string).unwrap_or_default();
        assert!(help.len() > 10, "--{id} has no help");
        let takes_value = arg.get_num_args().is_some_and(|n| n.takes_values())
            && !matches!(arg.get_action(), clap::ArgAction::SetTrue);
        let exempt = ["output", "scene"].contains(&id);
        if takes_value && !exempt {
            assert!(
                help.contains("[default") || !arg.get_default_values().is_empty(),
                "--{id}: no default in '{help}'"
            );
        }
    }
}

#[test]
fn preset_summaries_are_whole_sentences() {
    let out = skyrender(&["presets"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), skyrender::scene::PRESETS.len());
    for line in text.lines() {
        assert!(line.ends_with('.'), "cut: {line}");
        assert_eq!(
            line.matches('(').count(),
            line.matches(')').count(),
            "{line}"
        );
    }
    assert!(
        text.contains("its left edge; the centre looks north)."),
        "{text}"
    );
}

/// A PNG says it is sRGB and carries the scene and its exposure.
#[test]
fn png_files_carry_srgb_and_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sky.png");
    let out = skyrender(&[
        "render",
        "--preset",
        "sunset",
        "--width",
        "16",
        "--height",
        "8",
        "--spp",
        "1",
        "--exposure",
        "-3.5",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let reader = decoder.read_info().unwrap();
    let info = reader.info();
    assert!(info.srgb.is_some(), "no sRGB chunk");
    let text: std::collections::HashMap<String, String> = info
        .utf8_text
        .iter()
        .map(|c| (c.keyword.clone(), c.get_text().unwrap()))
        .collect();
    let scene = skyrender::Scene::from_toml(&text["skyrender:scene"]).unwrap();
    assert_eq!(scene.sun.elevation_deg, 2.0);
    assert_eq!(text["skyrender:exposure_ev"], "-3.5000");
}
