//! Reading the user's data files (phase functions, spectra, profiles):
//! one size limit, one error form naming the file, the line and the valid
//! form, and one per-process cache, so that a scene is checked
//! ([`crate::scene::Scene::validate`]) and rendered from the same numbers
//! even if the file changes in between.

use std::collections::HashMap;
use std::hash::Hash;
use std::path::Path;
use std::sync::{Arc, Mutex, OnceLock};

/// Largest data file read, bytes: 100 000 rows of a few numbers are a
/// few MB.
const MAX_BYTES: u64 = 16 << 20;

/// Reads the file at `path` and parses it with `parse`, whose error is a
/// line number (0: the file as a whole) and a reason; the error returned
/// names the file, the line and `valid_form`.
pub fn load<T>(
    path: &Path,
    valid_form: &str,
    parse: impl FnOnce(&str) -> Result<T, (usize, String)>,
) -> Result<T, String> {
    let fail = |line: usize, reason: String| {
        let place = if line == 0 {
            String::new()
        } else {
            format!(" line {line}")
        };
        format!(
            "'{}'{place}: {reason} (valid: {valid_form})",
            path.display()
        )
    };
    if path.is_dir() {
        return Err(fail(0, "is a directory".into()));
    }
    let metadata = std::fs::metadata(path).map_err(|e| fail(0, e.to_string()))?;
    if metadata.len() > MAX_BYTES {
        return Err(fail(0, "larger than 16 MiB".into()));
    }
    let text = std::fs::read_to_string(path).map_err(|e| fail(0, e.to_string()))?;
    parse(&text).map_err(|(line, reason)| fail(line, reason))
}

/// A per-process cache of loaded files by key.
pub type Cache<K, T> = OnceLock<Mutex<HashMap<K, Arc<T>>>>;

/// The value `cache` holds for `key`, or the one `load` gives (kept; an
/// error is not, so a corrected file is read afresh).
pub fn cached<K: Eq + Hash + Clone, T>(
    cache: &Cache<K, T>,
    key: K,
    load: impl FnOnce() -> Result<T, String>,
) -> Result<Arc<T>, String> {
    let cache = cache.get_or_init(|| Mutex::new(HashMap::new()));
    if let Some(value) = cache.lock().expect("cache lock").get(&key) {
        return Ok(Arc::clone(value));
    }
    let value = Arc::new(load()?);
    let mut cache = cache.lock().expect("cache lock");
    Ok(Arc::clone(cache.entry(key).or_insert(value)))
}
