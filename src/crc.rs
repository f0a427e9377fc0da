//! CRC-32 (IEEE 802.3, the one zlib's `crc32` computes): reflected polynomial 0xEDB88320, initial value and
//! final XOR 0xFFFFFFFF.
//!
//! Job: one home for the checksum several formats share: the parameter and log TOC CRCs
//! ([`crate::radio`]), the persistent parameters' EEPROM records ([`crate::system::persistent_params`]) and
//! the map memory's header. Bitwise, without a table, so that it is a `const fn` (the TOC CRCs are computed
//! at compile time) and takes no flash for a 1 KiB table.
//!
//! Non-goals: other polynomials, a table-driven fast path.
//! Cost: 8 shift-and-XOR steps per byte; memory: the 4-byte register.

/// Feeds `bytes` into a running CRC-32 register (reflected poly 0xEDB88320). Start with `0xFFFF_FFFF` and
/// XOR the result with `0xFFFF_FFFF` at the end (check value of "123456789" is 0xCBF43926).
pub const fn crc32_update(mut crc: u32, bytes: &[u8]) -> u32 {
    let mut i = 0;
    while i < bytes.len() {
        crc ^= bytes[i] as u32;
        let mut k = 0;
        while k < 8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
            k += 1;
        }
        i += 1;
    }
    crc
}

/// CRC-32 of `bytes` (init and xorout 0xFFFFFFFF).
pub const fn crc32(bytes: &[u8]) -> u32 {
    crc32_update(0xFFFF_FFFF, bytes) ^ 0xFFFF_FFFF
}
