//! A debug probe for the emulated core (`--probe`): the register file and the live part of the stack at a
//! moment the host picks (a panic line in the defmt log, the end of the run), so that where a task is parked,
//! or which call started a transfer, can be read back with `arm-none-eabi-addr2line -f -C -i -e ELF ADDR…`.
//!
//! Job: read r0–r15 through rsemu's debugger view (`host::gdb::target::MachineTarget`, the `gdb` feature; a
//! `dyn Device` has no route to the core's own type), then the words from SP upward that point into flash
//! with the Thumb bit set (return addresses, stale ones included: read them as candidates, not a backtrace).
//! Non-goals: unwinding (no CFI reader), changing anything in the machine. Units: addresses as the core sees
//! them. Memory: at most `STACK_WORDS` words.

use rsemu::host::gdb::target::{DebugTarget, MachineTarget};
use rsemu::machine::Machine;
use serde::Serialize;

/// How much of the stack above SP is scanned (4 KiB).
pub const STACK_WORDS: u32 = 1024;

/// What the probe saw.
#[derive(Debug, Clone, Serialize)]
pub struct Sample {
    /// Virtual ms of the sample.
    pub at_ms: u64,
    /// Why it was taken.
    pub why: String,
    /// r0–r12, sp, lr, pc.
    pub regs: Vec<String>,
    /// Code addresses found on the stack above SP, innermost first (Thumb bit cleared, minus 1 for a BL's
    /// return address would be the call itself; left as stored).
    pub stack_code: Vec<String>,
    /// The first [`RAW_WORDS`] words above SP as they are (arguments spilled by the callers).
    pub stack_words: Vec<String>,
}

/// Raw stack words kept in a sample.
pub const RAW_WORDS: u32 = 64;

/// Reads the core's registers (cpu 0) and scans the stack for return-address candidates.
pub fn sample(machine: &mut Machine, at_ms: u64, why: &str, code: std::ops::Range<u32>) -> Option<Sample> {
    let target = MachineTarget::new(machine);
    let mut regs = [0u32; 16];
    for (i, r) in regs.iter_mut().enumerate() {
        let bytes = target.read_register(0, i).ok()?;
        *r = u32::from_le_bytes(bytes.get(..4)?.try_into().ok()?);
    }
    let sp = regs[13];
    let mut stack_code = Vec::new();
    let mut stack_words = Vec::new();
    for k in 0..STACK_WORDS {
        let mut w = [0u8; 4];
        if target.read_memory(0, u64::from(sp) + u64::from(k) * 4, &mut w).is_err() {
            break;
        }
        let v = u32::from_le_bytes(w);
        if k < RAW_WORDS {
            stack_words.push(format!("{v:#x}"));
        }
        if v & 1 == 1 && code.contains(&(v & !1)) {
            stack_code.push(format!("{:#010x}@sp+{:#x}", v & !1, k * 4));
        }
    }
    Some(Sample {
        at_ms,
        why: why.to_string(),
        regs: regs.iter().map(|r| format!("{r:#010x}")).collect(),
        stack_code,
        stack_words,
    })
}
