//! Shared code for the host tests: small std-side maps and independent oracles.
//! The tests themselves live in `tests/`.

pub mod oracle;
