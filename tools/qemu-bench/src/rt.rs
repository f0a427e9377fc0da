//! The bare-metal runtime of the benchmark: vector table, reset handler and exception handler for QEMU's
//! mps2-an386 (Cortex-M4F), written for this crate. The linker script `qemu-bench.x` places the vector table at
//! 0x0 (its word 0, the initial stack pointer, is written by the script) and defines the `__data_*`, `__bss_*` and
//! `_stack_top` symbols used here.
//!
//! References: Arm, *ARMv7-M Architecture Reference Manual* (DDI 0403E), B1.5 "ARMv7-M exception model" (the
//! exception numbers, the vector table, the frame stacked on exception entry) and, in B3.2 "System Control
//! Space", the Coprocessor Access Control Register (CPACR, 0xE000_ED88); Arm, *Cortex-M4 Devices Generic User
//! Guide* (DUI 0553), "Enabling the FPU".
//!
//! Reset order, all of it before any Rust code runs (so no Rust code can observe uninitialised statics, and none
//! can touch a floating-point register while the FPU is still disabled, its reset state):
//! 1. enable the FPU: CPACR.CP10 = CP11 = 0b11 (full access), then `dsb` + `isb` so that the next instruction sees
//!    it — the target is `eabihf`, so compiled code may use FP registers anywhere, even in a function's prologue;
//! 2. copy `.data` from its load address in code memory to RAM;
//! 3. zero `.bss`;
//! 4. call [`crate::mcu::main`], which never returns (it exits QEMU through semihosting).
//!
//! The reset handler is therefore a naked function: its body is only the assembly below, with no compiler-made
//! prologue that could spill registers or use the FPU, and no Rust code (which the language lets assume that
//! statics hold their initial values from the start) runs before RAM is initialised.

use core::arch::naked_asm;

use cortex_m_semihosting::{debug, hprintln};

/// An exception handler: entered by the processor, never returns.
type Handler = unsafe extern "C" fn() -> !;

/// External interrupt lines of mps2-an386 given a vector (none is ever enabled: the NVIC resets with every
/// interrupt disabled and this program never writes it; the vectors exist so that a stray one reports itself).
const EXTERNAL_INTERRUPTS: usize = 32;

/// Vectors 1..=15 (the system exceptions) and 16.. (the external interrupts), right after the linker script's
/// initial stack pointer: Reset runs [`Reset`], every other exception reports itself through [`exception_entry`] and
/// fails the run. Exception numbers 7–10 and 13 are reserved and hold 0. (`Option` of a function pointer has the
/// pointer's size and layout, `None` being 0, so this is an array of 32-bit words; the Thumb bit of each address is
/// set by the linker, the handlers being Thumb functions.)
#[unsafe(link_section = ".vector_table.handlers")]
#[used]
static VECTORS: [Option<Handler>; 15 + EXTERNAL_INTERRUPTS] = {
    let mut v: [Option<Handler>; 15 + EXTERNAL_INTERRUPTS] = [Some(exception_entry); 15 + EXTERNAL_INTERRUPTS];
    v[0] = Some(Reset); // exception number n is at index n - 1
    v[6] = None;
    v[7] = None;
    v[8] = None;
    v[9] = None;
    v[12] = None;
    v
};

/// The reset handler (exception 1): FPU on, `.data` copied, `.bss` zeroed, then [`crate::mcu::main`].
///
/// # Safety
///
/// Only the processor may call this, out of reset, through the vector table: it overwrites all of `.data` and
/// `.bss`.
// SAFETY (of `naked`): the body is a single `naked_asm!` that never returns and needs no stack frame: it starts
// on the stack the processor loaded from the vector table (the top of RAM, 8-byte aligned as the AAPCS wants at
// a call), only uses r0–r3 before the call, and the call target is an `extern "C"` function taking no
// arguments. The memory it writes is exactly what the linker script reserves for `.data` and `.bss` (4-byte
// aligned bounds, so whole-word loops cover them), and nothing else runs yet. CPACR (0xE000_ED88) is the
// architectural FPU access control register of every ARMv7-M core with an FPU.
#[unsafe(naked)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn Reset() -> ! {
    naked_asm!(
        // 1. CPACR |= 0xF << 20: full access to CP10 and CP11 (the FPU); barriers so that it takes effect before
        //    the next instruction.
        "ldr r0, =0xE000ED88",
        "ldr r1, [r0]",
        "orr r1, r1, #0x00F00000",
        "str r1, [r0]",
        "dsb",
        "isb",
        // 2. .data: one word at a time from __data_load to __data_start..__data_end.
        "ldr r0, =__data_start",
        "ldr r1, =__data_end",
        "ldr r2, =__data_load",
        "1:",
        "cmp r0, r1",
        "bhs 2f",
        "ldr r3, [r2], #4",
        "str r3, [r0], #4",
        "b 1b",
        "2:",
        // 3. .bss: zero __bss_start..__bss_end.
        "ldr r0, =__bss_start",
        "ldr r1, =__bss_end",
        "movs r2, #0",
        "3:",
        "cmp r0, r1",
        "bhs 4f",
        "str r2, [r0], #4",
        "b 3b",
        "4:",
        // 4. The benchmark; it exits QEMU and never returns (should it, `udf` faults into `exception_entry`).
        "bl {main}",
        "udf #0",
        ".ltorg",
        main = sym crate::mcu::main,
    )
}

/// Every exception but Reset: passes the stacked frame and the exception number to [`report_exception`].
///
/// # Safety
///
/// Only the processor may call this, through the vector table.
// SAFETY (of `naked`): five instructions and a tail call, no stack use: r0 = the stack pointer the processor
// pushed the exception frame on (EXC_RETURN bit 2 in lr selects MSP or PSP; this program only ever uses MSP),
// r1 = IPSR (the exception number), then a branch to an `extern "C" fn(*const u32, u32) -> !`.
#[unsafe(naked)]
unsafe extern "C" fn exception_entry() -> ! {
    naked_asm!(
        "tst lr, #4",
        "ite eq",
        "mrseq r0, msp",
        "mrsne r0, psp",
        "mrs r1, ipsr",
        "b {report}",
        report = sym report_exception,
    )
}

unsafe extern "C" {
    /// `qemu-bench.x`: the bottom of RAM.
    static __ram_start: u8;
    /// `qemu-bench.x`: the top of RAM, where the stack starts.
    static _stack_top: u8;
}

/// Report an unexpected exception (`error=<name> number=<exception number> pc=<stacked pc>`) and exit QEMU with
/// a failure status.
extern "C" fn report_exception(frame: *const u32, number: u32) -> ! {
    /// The exception frame: r0–r3, r12, lr, the return address, xPSR.
    const FRAME_WORDS: usize = 8;
    /// The return address: the pc of the faulting or interrupted instruction.
    const RETURN_ADDRESS: usize = 6;
    let ram = (&raw const __ram_start).addr()..(&raw const _stack_top).addr();
    let in_ram = frame.is_aligned()
        && frame.addr() >= ram.start
        && frame
            .addr()
            .checked_add(4 * FRAME_WORDS)
            .is_some_and(|end| end <= ram.end);
    let name = match number {
        2 => "nmi",
        3 => "hardfault",
        4 => "memmanage",
        5 => "busfault",
        6 => "usagefault",
        11 => "svcall",
        12 => "debugmonitor",
        14 => "pendsv",
        15 => "systick",
        _ => "interrupt",
    };
    if in_ram {
        // SAFETY: `frame` is the stack pointer right after exception entry, where the processor stacked the
        // 8-word exception frame, and it was just checked to be word-aligned with all 8 words in RAM, which is
        // always mapped and readable; a volatile read takes the word as the processor wrote it.
        let pc = unsafe { frame.add(RETURN_ADDRESS).read_volatile() };
        hprintln!("error={} number={} pc={:#010x}", name, number, pc);
    } else {
        // The stack pointer left RAM (a stack overflow): there is no frame to read.
        hprintln!("error={} number={} sp={:#010x}", name, number, frame.addr());
    }
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
