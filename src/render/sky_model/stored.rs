//! The model's tables kept on disk, so that the app's first frame after a
//! start (or after going back to an atmosphere seen before) is the tables'
//! lookup, tens of milliseconds, not their making, half a second.
//!
//! A file holds one atmosphere's Ψ table, its zenith factors and the sky's
//! irradiance on the ground, as little-endian `f64`s (the factors as the
//! `f32`s they are kept in), after the build that
//! made them and the optics they were made of (the [`fingerprint`] the
//! in-memory cache compares), and before a checksum of all of it. It is
//! read back only if every one of those matches bit for bit and every
//! count is the one this build makes: the tables read are then the very
//! numbers the build would make, and an image is the same whether they
//! came from disk or not. The build is told by the running executable's
//! length and modification time (any rebuild or reinstall changes them):
//! a file another build wrote is never trusted, whatever changed in the
//! code that makes the tables.
//!
//! Where the files go: `$SKYRENDER_CACHE_DIR` (set empty: nowhere), else
//! `$XDG_CACHE_HOME/skyrender`, else `~/.cache/skyrender` (on Windows
//! `%LOCALAPPDATA%\skyrender`), in a `sky-model` folder. At most
//! [`MAX_FILES`] are kept, the least recently used removed first. Every
//! failure (no such folder, a full disk, a corrupt or foreign file) only
//! means the tables are made anew; writes are atomic
//! ([`crate::output::replace_file`]), so a killed process leaves nothing.
//!
//! [`fingerprint`]: super::orders

use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{SystemTime, UNIX_EPOCH};

use super::optics::{Factor, MsTable, SkyIrradiance, Spectrum, NODES};

/// Files kept in the folder, at most (each about 16 MB).
pub(super) const MAX_FILES: usize = 8;

/// The first bytes of every file (the format's version in its last).
const MAGIC: &[u8; 8] = b"SKYMDL\x00\x03";

/// The folder the tables go to, if any (see the module's documentation).
pub(super) fn default_folder() -> Option<PathBuf> {
    let base = match std::env::var_os("SKYRENDER_CACHE_DIR") {
        Some(dir) if dir.is_empty() => return None,
        Some(dir) => PathBuf::from(dir),
        None => {
            let xdg = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty());
            let home = || std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache"));
            let local = || std::env::var_os("LOCALAPPDATA").map(PathBuf::from);
            xdg.map(PathBuf::from)
                .or_else(home)
                .or_else(local)?
                .join("skyrender")
        }
    };
    Some(base.join("sky-model"))
}

/// FNV-1a over 64-bit words (the bytes' tail zero-padded): the files'
/// names and checksums, not a defence against a forger, only against the
/// wrong file and a damaged one. Word by word, it reads a file's 8 MB in
/// about a millisecond.
#[derive(Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }

    fn bytes(mut self, bytes: &[u8]) -> Self {
        for word in bytes.chunks(8) {
            let mut padded = [0; 8];
            padded[..word.len()].copy_from_slice(word);
            self.0 = (self.0 ^ u64::from_le_bytes(padded)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        self
    }
}

/// The running build's identity: its version and its executable's length
/// and modification time. `None` where they cannot be read (then nothing
/// is kept on disk).
fn build_identity() -> Option<u64> {
    static IDENTITY: OnceLock<Option<u64>> = OnceLock::new();
    *IDENTITY.get_or_init(|| {
        let meta = std::fs::metadata(std::env::current_exe().ok()?).ok()?;
        let modified = meta.modified().ok()?.duration_since(UNIX_EPOCH).ok()?;
        let hash = Fnv::new()
            .bytes(env!("CARGO_PKG_VERSION").as_bytes())
            .bytes(&meta.len().to_le_bytes())
            .bytes(&modified.as_nanos().to_le_bytes());
        Some(hash.0)
    })
}

/// The header every file of these optics starts with: magic, build,
/// fingerprint (its length, then its numbers).
fn header(build: u64, fingerprint: &[f64]) -> Vec<u8> {
    let mut out = MAGIC.to_vec();
    out.extend(build.to_le_bytes());
    out.extend((fingerprint.len() as u64).to_le_bytes());
    for v in fingerprint {
        out.extend(v.to_le_bytes());
    }
    out
}

/// The file of these optics in `folder`: named by a hash of its header.
fn path_of(folder: &Path, header: &[u8]) -> PathBuf {
    folder.join(format!("{:016x}.bin", Fnv::new().bytes(header).0))
}

/// The bytes a file holds after its header, before its checksum: every
/// number of the tables, bit for bit.
pub(super) fn body(ms: &MsTable, sky: &SkyIrradiance) -> Vec<u8> {
    let wide = |v: &f64| v.to_le_bytes();
    let mut out = Vec::new();
    out.extend(ms.values.iter().flatten().flatten().flat_map(wide));
    let factors = ms.zenith_factors.iter().flatten().flatten();
    out.extend(factors.flat_map(|f| f.to_le_bytes()));
    out.extend(sky.values.iter().flatten().flat_map(wide));
    out
}

/// Writes the tables of `fingerprint`'s optics into `folder` (made if
/// missing), then removes the least recently used files past
/// [`MAX_FILES`].
pub(super) fn store(
    folder: &Path,
    fingerprint: &[f64],
    ms: &MsTable,
    sky: &SkyIrradiance,
) -> io::Result<()> {
    let build = build_identity().ok_or_else(|| io::Error::other("no build identity"))?;
    std::fs::create_dir_all(folder)?;
    let header = header(build, fingerprint);
    let path = path_of(folder, &header);
    crate::output::replace_file(
        &path,
        |e| e,
        |w| {
            let body = body(ms, sky);
            let hash = Fnv::new().bytes(&header).bytes(&body);
            w.write_all(&header)?;
            w.write_all(&body)?;
            w.write_all(&hash.0.to_le_bytes())
        },
    )?;
    prune(folder, MAX_FILES);
    Ok(())
}

/// The tables of `fingerprint`'s optics from `folder`, if a file of this
/// build holds them whole. `template` gives the tables' shape (their
/// counts and the planet's radii); only its numbers are replaced.
pub(super) fn load(
    folder: &Path,
    fingerprint: &[f64],
    template: (f64, f64),
) -> Option<(MsTable, SkyIrradiance)> {
    let header = header(build_identity()?, fingerprint);
    let path = path_of(folder, &header);
    let mut bytes = Vec::new();
    std::fs::File::open(&path)
        .ok()?
        .read_to_end(&mut bytes)
        .ok()?;
    let tables = parse(&bytes, &header, template)?;
    // Used: the last to be pruned.
    if let Ok(file) = std::fs::File::options().append(true).open(&path) {
        let _ = file.set_modified(SystemTime::now());
    }
    Some(tables)
}

/// The tables in `bytes`, if they begin with `header`, hold exactly the
/// counts of this build's tables, every number finite, and end with the
/// checksum of all before it.
fn parse(
    bytes: &[u8],
    header: &[u8],
    (planet_radius_m, top_m): (f64, f64),
) -> Option<(MsTable, SkyIrradiance)> {
    use super::optics::{
        E_ZENITHS, MS_ALTITUDES, MS_VIEW_ANGLES, MS_VIEW_AZIMUTHS, MS_VIEW_ZENITHS, MS_ZENITHS,
    };
    let cells = MS_ALTITUDES * MS_ZENITHS;
    let counts = [
        cells * MS_VIEW_ANGLES,
        cells * MS_VIEW_ZENITHS * MS_VIEW_AZIMUTHS,
        E_ZENITHS,
    ];
    let (wide, narrow) = (
        2 * NODES * counts[0] + NODES * counts[2],
        2 * NODES * counts[1],
    );
    if bytes.len() != header.len() + 8 * wide + 4 * narrow + 8 || !bytes.starts_with(header) {
        return None;
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    if Fnv::new().bytes(body).0.to_le_bytes() != sum {
        return None;
    }
    let body = &body[header.len()..];
    let (values, rest) = body.split_at(8 * 2 * NODES * counts[0]);
    let (factors, sky) = rest.split_at(4 * narrow);
    // Each number read straight into its place; a number not finite
    // rejects the file.
    let f64_at = |c: &[u8]| f64::from_le_bytes(c.try_into().unwrap_or_default());
    let spectrum =
        |bytes: &[u8]| -> Spectrum { std::array::from_fn(|n| f64_at(&bytes[8 * n..8 * n + 8])) };
    let width = 8 * NODES;
    let values: Vec<[Spectrum; 2]> = values
        .chunks_exact(2 * width)
        .map(|c| [spectrum(&c[..width]), spectrum(&c[width..])])
        .collect();
    let factors: Vec<[Factor; 2]> = factors
        .chunks_exact(2 * 4 * NODES)
        .map(|c| {
            [0, 1].map(|x| {
                std::array::from_fn(|n| {
                    let at = 4 * (x * NODES + n);
                    f32::from_le_bytes(c[at..at + 4].try_into().unwrap_or_default())
                })
            })
        })
        .collect();
    let sky: Vec<Spectrum> = sky.chunks_exact(width).map(spectrum).collect();
    let finite = values.iter().flatten().flatten().all(|v| v.is_finite())
        && factors.iter().flatten().flatten().all(|v| v.is_finite())
        && sky.iter().flatten().all(|v| v.is_finite());
    if !finite {
        return None;
    }
    let ms = MsTable {
        planet_radius_m,
        top_m,
        values,
        zenith_sums: Vec::new(),
        zenith_factors: factors,
    };
    let sky = SkyIrradiance { values: sky };
    Some((ms, sky))
}

/// Removes the least recently modified table files in `folder` past the
/// `keep` newest, best effort.
fn prune(folder: &Path, keep: usize) {
    let Ok(entries) = std::fs::read_dir(folder) else {
        return;
    };
    let mut files: Vec<(SystemTime, PathBuf)> = entries
        .filter_map(Result::ok)
        .filter(|e| e.path().extension().is_some_and(|x| x == "bin"))
        .filter_map(|e| Some((e.metadata().ok()?.modified().ok()?, e.path())))
        .collect();
    if files.len() <= keep {
        return;
    }
    files.sort_by_key(|f| std::cmp::Reverse(f.0));
    for (_, path) in files.drain(keep..) {
        let _ = std::fs::remove_file(path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oldest files go past the count kept; other files stay.
    #[test]
    fn pruning_keeps_the_most_recently_used() {
        let folder = tempfile::tempdir().unwrap();
        let now = SystemTime::now();
        for i in 0..12_u64 {
            let path = folder.path().join(format!("{i:016x}.bin"));
            std::fs::write(&path, b"x").unwrap();
            let age = std::time::Duration::from_secs(100 * (12 - i));
            let file = std::fs::File::options().append(true).open(&path).unwrap();
            file.set_modified(now - age).unwrap();
        }
        std::fs::write(folder.path().join("notes.txt"), b"kept").unwrap();
        prune(folder.path(), MAX_FILES);
        let mut left: Vec<String> = std::fs::read_dir(folder.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        let mut expected: Vec<String> = (12 - MAX_FILES as u64..12)
            .map(|i| format!("{i:016x}.bin"))
            .collect();
        expected.push("notes.txt".into());
        assert_eq!(left, expected);
    }

    /// `SKYRENDER_CACHE_DIR` set empty keeps nothing on disk.
    #[test]
    fn the_folder_follows_the_environment() {
        // Read only: other tests may run meanwhile, and the variable is
        // not set by the test harness.
        match std::env::var_os("SKYRENDER_CACHE_DIR") {
            Some(dir) if dir.is_empty() => assert_eq!(default_folder(), None),
            Some(dir) => assert_eq!(default_folder(), Some(PathBuf::from(dir).join("sky-model"))),
            None => assert!(default_folder().is_none_or(|f| f.ends_with("skyrender/sky-model"))),
        }
    }
}
