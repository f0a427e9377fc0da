//! The build's git revision as stock's `firmware` parameter group publishes it:
//! `firmware.revision0` (uint32, read-only) = the first 8 hex digits of the commit hash, `firmware.revision1`
//! (uint16, read-only) = the next 4, `firmware.modified` (uint8, read-only) = 1 when the firmware's tracked
//! inputs (`src`, `build.rs`, `Cargo.toml`, `memory.x`) differed from that commit at build time. Stock
//! derives the same values in `tools/make/versionTemplate.py` (`irevision0 = "0x" + revision[0:8]`,
//! `irevision1 = "0x" + revision[8:12]`) and declares them in
//! `src/utils/src/version.tmpl` (`PARAM_UINT32 | PARAM_RONLY revision0`, `PARAM_UINT16 | PARAM_RONLY
//! revision1`, `PARAM_UINT8 | PARAM_RONLY modified`); cfclient's About dialog shows
//! them as `{revision0:x}{revision1:x} (MODIFIED|CLEAN)` (`cfclient/ui/dialogs/about.py`).
//!
//! Job: parse the strings `build.rs` sets (`CFNAV_GIT_REVISION`, `CFNAV_GIT_MODIFIED`) at compile time.
//! Non-goals: tags, branch names (stock's string-only fields have no parameter). Memory: three constants.
//! A build without git (a source tarball) reads revision 0, not modified.

/// The full commit hash the build came from (`""` when git was unavailable).
pub const GIT_REVISION: &str = env!("CFNAV_GIT_REVISION");

/// `firmware.revision0`: the hash's first 8 hex digits.
pub const REVISION0: u32 = hex_prefix(GIT_REVISION, 0, 8) as u32;
/// `firmware.revision1`: the hash's hex digits 8..12.
pub const REVISION1: u16 = hex_prefix(GIT_REVISION, 8, 4) as u16;
/// `firmware.modified`: 1 when the working tree differed from the commit at build time.
pub const MODIFIED: u8 = if matches!(env!("CFNAV_GIT_MODIFIED").as_bytes(), [b'1']) {
    1
} else {
    0
};

/// The `len` hex digits of `s` from `start` as a number; 0 when `s` is too short or holds a non-hex digit.
pub const fn hex_prefix(s: &str, start: usize, len: usize) -> u64 {
    let b = s.as_bytes();
    if b.len() < start + len || len > 16 {
        return 0;
    }
    let mut v = 0u64;
    let mut i = start;
    while i < start + len {
        let d = match b[i] {
            c @ b'0'..=b'9' => c - b'0',
            c @ b'a'..=b'f' => c - b'a' + 10,
            c @ b'A'..=b'F' => c - b'A' + 10,
            _ => return 0,
        };
        v = (v << 4) | d as u64;
        i += 1;
    }
    v
}
