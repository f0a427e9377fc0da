//! A table-of-contents cache on disk for crazyflie-lib's [`TocCache`]: one file per key in a folder.
//!
//! Job: skip the TOC download on the next connection to the same firmware (over the radio the stock firmware's
//! hundreds of entries take seconds). crazyflie-lib builds the key from a cache format version and the TOC's
//! CRC32 (`crazyflie-lib-0.8.2/src/crtp_utils.rs`, `fetch_toc`); a file is named by the key in hex.
//!
//! Non-goals: eviction, locking between processes (a file is written to a temporary name and renamed, so a
//! reader never sees half a file). A cache that cannot be read or written is simply not used.
//!
//! Memory: nothing is held; each call reads or writes one file.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crazyflie_lib::TocCache;

/// The TOC cache in `dir` (created on the first store), or no cache at all.
#[derive(Clone, Debug)]
pub struct DirTocCache {
    dir: Option<PathBuf>,
}

impl DirTocCache {
    /// A cache kept in `dir`.
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self { dir: Some(dir.into()) }
    }

    /// No cache: every connection downloads the TOCs.
    pub fn disabled() -> Self {
        Self { dir: None }
    }

    /// `$XDG_CACHE_HOME/cfnav/toc`, else `$HOME/.cache/cfnav/toc`; `None` if neither variable is set.
    pub fn default_dir() -> Option<PathBuf> {
        let base = match std::env::var_os("XDG_CACHE_HOME") {
            Some(d) if !d.is_empty() => PathBuf::from(d),
            _ => PathBuf::from(std::env::var_os("HOME").filter(|h| !h.is_empty())?).join(".cache"),
        };
        Some(base.join("cfnav").join("toc"))
    }

    /// The folder, if the cache is on.
    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    fn path(&self, key: &[u8]) -> Option<PathBuf> {
        let dir = self.dir.as_ref()?;
        let mut name = String::with_capacity(key.len() * 2 + 5);
        for b in key {
            let _ = write!(name, "{b:02x}");
        }
        name.push_str(".json");
        Some(dir.join(name))
    }
}

impl TocCache for DirTocCache {
    fn get_toc(&self, key: &[u8]) -> Option<String> {
        std::fs::read_to_string(self.path(key)?).ok()
    }

    fn store_toc(&self, key: &[u8], toc: &str) {
        let (Some(dir), Some(path)) = (self.dir.as_ref(), self.path(key)) else {
            return;
        };
        let tmp = path.with_extension(format!("json.tmp{}", std::process::id()));
        let stored = std::fs::create_dir_all(dir)
            .and_then(|()| std::fs::write(&tmp, toc))
            .and_then(|()| std::fs::rename(&tmp, &path));
        if stored.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stores_and_finds_by_key() {
        let dir = std::env::temp_dir().join(format!("cfnav-toc-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let cache = DirTocCache::new(dir.join("nested"));
        let key = [1u8, 0xAB, 0x00, 0x12, 0xFF];
        assert_eq!(cache.get_toc(&key), None);
        cache.store_toc(&key, "{\"a\":1}");
        assert_eq!(cache.get_toc(&key).as_deref(), Some("{\"a\":1}"));
        assert!(dir.join("nested").join("01ab0012ff.json").is_file());
        // Another CRC is another entry.
        assert_eq!(cache.get_toc(&[1, 0xAB, 0x00, 0x12, 0xFE]), None);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn an_unwritable_cache_is_ignored() {
        // A folder below a file cannot be created: the store fails quietly, the get finds nothing.
        let file = std::env::temp_dir().join(format!("cfnav-toc-file-{}", std::process::id()));
        std::fs::write(&file, "x").unwrap();
        let cache = DirTocCache::new(file.join("toc"));
        cache.store_toc(&[1, 2, 3, 4, 5], "{}");
        assert_eq!(cache.get_toc(&[1, 2, 3, 4, 5]), None);
        let _ = std::fs::remove_file(&file);
    }

    #[test]
    fn a_disabled_cache_finds_nothing() {
        let cache = DirTocCache::disabled();
        cache.store_toc(&[1, 2, 3, 4, 5], "{}");
        assert_eq!(cache.get_toc(&[1, 2, 3, 4, 5]), None);
        assert_eq!(cache.dir(), None);
    }
}
