//! Replacing a file atomically, leaving nothing behind on any interruption.
//!
//! A new file is written beside its target and only then put in its place,
//! so a reader sees the old file or the complete new one, never half of it.
//! What is written first must not outlive the process when it is killed:
//!
//! - **Linux:** the data go to an *unnamed* file (`open(dir, O_TMPFILE)`,
//!   open(2)), which has no directory entry until it is complete. Then
//!   `linkat(2)` gives it the target's name when there is no target, or a
//!   hidden name that `rename(2)` moves over the target in the same
//!   instant. A process killed while writing, even by `SIGKILL`, leaves
//!   nothing: the kernel frees an unnamed file with its last descriptor.
//! - **Elsewhere,** or on a file system without `O_TMPFILE`: a hidden named
//!   file `.skyrender-<pid>-XXXXXX.tmp`. Each is recorded while it exists;
//!   `SIGINT`, `SIGTERM` and `SIGHUP` ([`remove_on_signals`]) and the app's
//!   exit ([`remove_pending_files`]) delete the recorded ones, and the next
//!   write into the same directory sweeps those of processes that no longer
//!   run ([`sweep_stale`], Linux) — a `SIGKILL` cannot be caught.

use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};

/// The prefix of every temporary file's name (hidden on Unix).
const PREFIX: &str = ".skyrender-";
/// The suffix of every temporary file's name.
const SUFFIX: &str = ".tmp";

/// Named temporary files this process has open, to delete on a signal.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // A panic elsewhere while holding the lock leaves the list valid.
    PENDING.lock().unwrap_or_else(PoisonError::into_inner)
}

fn register(path: &Path) {
    pending().push(path.to_path_buf());
}

fn unregister(path: &Path) {
    pending().retain(|p| p != path);
}

/// Deletes the named temporary files this process is writing. Called where
/// the process ends without unwinding (a signal, the app's window closing
/// while an export runs); a write that goes on afterwards fails cleanly
/// when it renames its file.
pub fn remove_pending_files() {
    for path in pending().drain(..) {
        // Already gone (renamed over its target a moment ago): nothing to do.
        let _ = std::fs::remove_file(path);
    }
}

/// Starts a thread that, on `SIGINT`, `SIGTERM` or `SIGHUP`, deletes the
/// pending temporary files ([`remove_pending_files`]) and then ends the
/// process as the signal would have (the shell sees "killed by signal").
/// Without it, Ctrl-C during a write left its temporary file behind on
/// systems without unnamed files. Does nothing off Unix.
pub fn remove_on_signals() -> io::Result<()> {
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
        std::thread::Builder::new()
            .name("skyrender-signals".into())
            .spawn(move || {
                if let Some(signal) = signals.forever().next() {
                    remove_pending_files();
                    // Re-raise with the default action; exit as a shell
                    // would report it should that fail.
                    let _ = signal_hook::low_level::emulate_default_handler(signal);
                    std::process::exit(128 + signal);
                }
            })?;
    }
    Ok(())
}

/// A file being written, to be put in place by [`PendingFile::commit`];
/// dropped uncommitted, it leaves nothing behind.
pub struct PendingFile {
    file: File,
    name: Name,
}

enum Name {
    /// An `O_TMPFILE` file in this directory, without a name yet.
    #[cfg(target_os = "linux")]
    Unnamed(PathBuf),
    /// A hidden named file, recorded in [`PENDING`].
    Named(Recorded),
}

/// A named temporary file, deleted and its record dropped when dropped.
struct Recorded(Option<tempfile::TempPath>);

impl Drop for Recorded {
    fn drop(&mut self) {
        if let Some(temp) = self.0.take() {
            let key = temp.to_path_buf();
            // Deleted before its record goes: a signal in between finds it
            // recorded, and its removal of a missing file is harmless.
            drop(temp);
            unregister(&key);
        }
    }
}

impl PendingFile {
    /// A new empty file in `dir` (mode 0o666 minus the umask on Unix, as
    /// `File::create` gives; tempfile's default is a private 0o600).
    pub fn create_in(dir: &Path) -> io::Result<Self> {
        sweep_stale(dir);
        #[cfg(target_os = "linux")]
        if Path::new("/proc/self/fd").is_dir() {
            use rustix::fs::{Mode, OFlags};
            // Read and write: the EXR writer reads its header back to sort it.
            let flags = OFlags::RDWR | OFlags::TMPFILE | OFlags::CLOEXEC;
            // Any failure (a file system without O_TMPFILE answers
            // EOPNOTSUPP, an old kernel EISDIR) falls back to a named
            // file, whose own error, if any, is the one to report.
            if let Ok(fd) = rustix::fs::open(dir, flags, Mode::from_raw_mode(0o666)) {
                return Ok(Self {
                    file: File::from(fd),
                    name: Name::Unnamed(dir.to_path_buf()),
                });
            }
        }
        let mut builder = tempfile::Builder::new();
        let prefix = format!("{PREFIX}{}-", std::process::id());
        builder.prefix(&prefix).suffix(SUFFIX);
        #[cfg(unix)]
        builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
        // The list is held across the creation, so a signal's clean-up
        // cannot run between the file's creation and its record.
        let mut list = pending();
        let (file, path) = builder.tempfile_in(dir)?.into_parts();
        list.push(path.to_path_buf());
        Ok(Self {
            file,
            name: Name::Named(Recorded(Some(path))),
        })
    }

    /// The file, to write into.
    pub fn file_mut(&mut self) -> &mut File {
        &mut self.file
    }

    /// The file, to sync or set permissions on.
    pub fn file(&self) -> &File {
        &self.file
    }

    /// Puts the file at `path`, replacing what was there in one step.
    pub fn commit(self, path: &Path) -> io::Result<()> {
        match self.name {
            #[cfg(target_os = "linux")]
            Name::Unnamed(dir) => link_unnamed(&self.file, &dir, path),
            Name::Named(mut recorded) => {
                let temp = recorded.0.take().expect("a recorded file until committed");
                let key = temp.to_path_buf();
                // On failure the error's TempPath, dropped, deletes the file.
                let result = temp.persist(path).map(drop).map_err(|e| e.error);
                unregister(&key);
                result
            }
        }
    }
}

/// Names the unnamed `file` (in `dir`) `path`: directly when nothing is
/// there, else under a hidden name renamed over `path`.
#[cfg(target_os = "linux")]
fn link_unnamed(file: &File, dir: &Path, path: &Path) -> io::Result<()> {
    use rustix::fs::{AtFlags, CWD};
    use std::os::fd::AsRawFd;
    let proc_path = format!("/proc/self/fd/{}", file.as_raw_fd());
    let link =
        |to: &Path| rustix::fs::linkat(CWD, proc_path.as_str(), CWD, to, AtFlags::SYMLINK_FOLLOW);
    match link(path) {
        Ok(()) => return Ok(()),
        Err(rustix::io::Errno::EXIST) => {}
        Err(e) => return Err(e.into()),
    }
    let pid = std::process::id();
    for attempt in 0..100u32 {
        let temp = dir.join(format!(
            "{PREFIX}{pid}-{:06x}{SUFFIX}",
            fastrand_like(attempt) & 0xff_ffff
        ));
        // Recorded first, so a signal between the link and the rename
        // finds it.
        register(&temp);
        match link(&temp) {
            Ok(()) => {
                let result = std::fs::rename(&temp, path);
                if result.is_err() {
                    let _ = std::fs::remove_file(&temp);
                }
                unregister(&temp);
                return result;
            }
            Err(rustix::io::Errno::EXIST) => unregister(&temp),
            Err(e) => {
                unregister(&temp);
                return Err(e.into());
            }
        }
    }
    Err(io::Error::new(
        io::ErrorKind::AlreadyExists,
        "no free temporary name in 100 tries",
    ))
}

/// A name suffix that differs between attempts, processes and instants.
#[cfg(target_os = "linux")]
fn fastrand_like(attempt: u32) -> u32 {
    use std::hash::{BuildHasher, Hasher};
    let mut hasher = std::collections::hash_map::RandomState::new().build_hasher();
    hasher.write_u32(attempt);
    hasher.finish() as u32
}

/// How long a stale-looking temporary file must have been left untouched
/// before it is swept: a writer in another PID namespace (a container
/// sharing the directory) is not visible in `/proc`, but its file's
/// modification time moves while it writes.
const STALE_AFTER: std::time::Duration = std::time::Duration::from_mins(1);

/// Deletes, best effort, the temporary files in `dir` that processes which
/// no longer run left behind (killed by `SIGKILL` while writing a named
/// file). Only names of this module's pattern with a PID are touched. Linux
/// only (liveness from `/proc`); elsewhere nothing.
pub fn sweep_stale(dir: &Path) {
    if !cfg!(target_os = "linux") || !Path::new("/proc/self").is_dir() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(stale_pattern_pid) else {
            continue;
        };
        if pid == std::process::id() || Path::new(&format!("/proc/{pid}")).exists() {
            continue;
        }
        let old = entry
            .metadata()
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|age| age >= STALE_AFTER);
        if old && entry.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The PID in a name `.skyrender-<pid>-<random>.tmp`, if it is one.
fn stale_pattern_pid(name: &str) -> Option<u32> {
    let rest = name.strip_prefix(PREFIX)?.strip_suffix(SUFFIX)?;
    let (pid, random) = rest.split_once('-')?;
    if random.is_empty() || !random.chars().all(|c| c.is_ascii_alphanumeric()) {
        return None;
    }
    pid.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn hidden_files(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with('.'))
            .collect()
    }

    #[test]
    fn a_dropped_file_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let mut file = PendingFile::create_in(dir.path()).unwrap();
        file.file_mut().write_all(b"half").unwrap();
        drop(file);
        assert!(hidden_files(dir.path()).is_empty());
        assert!(pending().iter().all(|p| !p.starts_with(dir.path())));
    }

    #[test]
    fn commit_creates_and_replaces() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.bin");
        for text in ["first", "second"] {
            let mut file = PendingFile::create_in(dir.path()).unwrap();
            file.file_mut().write_all(text.as_bytes()).unwrap();
            file.commit(&target).unwrap();
            assert_eq!(std::fs::read_to_string(&target).unwrap(), text);
            assert!(hidden_files(dir.path()).is_empty());
        }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn the_file_has_no_name_while_written_on_linux() {
        let dir = tempfile::tempdir().unwrap();
        let file = PendingFile::create_in(dir.path()).unwrap();
        // tmpfs and ext4 (where the tests run) take O_TMPFILE.
        assert!(matches!(file.name, Name::Unnamed(_)));
        assert!(std::fs::read_dir(dir.path()).unwrap().next().is_none());
    }

    #[test]
    fn pending_named_files_are_removed_on_request() {
        let dir = tempfile::tempdir().unwrap();
        let mut builder = tempfile::Builder::new();
        builder.prefix(".skyrender-1-").suffix(SUFFIX);
        let (_, path) = builder.tempfile_in(dir.path()).unwrap().into_parts();
        let path = path.keep().unwrap();
        register(&path);
        remove_pending_files();
        assert!(!path.exists());
    }

    #[test]
    fn stale_files_of_dead_processes_are_swept() {
        if !cfg!(target_os = "linux") {
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        // PID 4194304 is above Linux's largest (PID_MAX_LIMIT = 2^22).
        let dead = dir.path().join(".skyrender-4194304-abc123.tmp");
        let live = dir
            .path()
            .join(format!(".skyrender-{}-abc123.tmp", std::process::id()));
        let fresh_dead = dir.path().join(".skyrender-4194304-fresh1.tmp");
        let other = dir.path().join(".skyrender-notes.tmp");
        for path in [&dead, &live, &fresh_dead, &other] {
            std::fs::write(path, b"x").unwrap();
        }
        let long_ago = std::time::SystemTime::now() - 2 * STALE_AFTER;
        for path in [&dead, &live, &other] {
            File::options()
                .write(true)
                .open(path)
                .unwrap()
                .set_modified(long_ago)
                .unwrap();
        }
        sweep_stale(dir.path());
        assert!(!dead.exists());
        assert!(live.exists() && fresh_dead.exists() && other.exists());
    }

    #[test]
    fn the_pattern_reads_only_our_names() {
        assert_eq!(stale_pattern_pid(".skyrender-123-aB9xYz.tmp"), Some(123));
        assert_eq!(stale_pattern_pid(".skyrender-aB9xYz.tmp"), None);
        assert_eq!(stale_pattern_pid(".skyrender-123-.tmp"), None);
        assert_eq!(stale_pattern_pid("skyrender-123-abc.tmp"), None);
        assert_eq!(stale_pattern_pid(".skyrender-123-abc.exr"), None);
    }
}
