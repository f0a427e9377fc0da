//! Checks of the emulated Cortex-M4 against the architecture, where the cfnav image depends on a detail the
//! emulator once got wrong.
//!
//! Job: run a few hand-assembled Thumb instructions on the same machine `cfnav-pil` builds ([`Board`]), with
//! SysTick interrupting them every few cycles, and read the registers back. The one detail today: exception
//! entry must stack ITSTATE with xPSR and the return must restore it (ARMv7-M ARM, DDI 0403E, B1.5.6
//! PushStack and B1.5.8 ExceptionReturn), so an interrupt inside an `IT` block leaves the rest of the block
//! conditional. rsemu 0.0.7 stacked xPSR with the IT bits cleared; `patches/` fixes it, and
//! `an_interrupt_inside_an_it_block_keeps_its_condition` fails without the patch (docs/pil.md). The second:
//! a core asleep in `WFI` is woken by SysTick on the very cycle the counter reaches zero, also when the
//! emulator charges its idle cycles a budget at a time (`patches/rsemu-0.0.7-v7m-sleep-skip.patch`), which
//! `a_sleeping_core_wakes_on_the_systick_cycle` checks from the cycle counter read in the handler. The third:
//! exception entry must leave FPSCR alone (DDI 0403E B1.5.6 `ExceptionTaken`; `ExecuteFPCheck` gives a
//! handler FPDSCR's AHP/DN/FZ/RMode at its first floating-point instruction, never the flags), so an interrupt
//! between a `vcmp` and its `vmrs APSR_nzcv, fpscr` changes nothing; rsemu 0.0.7 loaded all of FPDSCR at
//! entry (`patches/rsemu-0.0.7-v7m-fpscr-flags.patch`), which
//! `an_interrupt_between_a_vcmp_and_its_vmrs_keeps_the_fpscr_flags` catches (402 wrong `addpl`s in 2 ms).
//! Non-goals: an instruction-set test suite (rsemu has its own corpus). Units: addresses as the core sees them.

#[cfg(test)]
mod tests {
    use rsemu::host::gdb::target::{DebugTarget, MachineTarget};

    use crate::board::Board;
    use crate::deck::Fitted;
    use crate::devices::Faults;

    /// Flash offset of the program (above the vector table) and the initial stack pointer.
    const CODE: usize = 0x100;
    const STACK_TOP: u32 = 0x2000_1000;
    /// SysTick's first reload (SYST_RVR); the handler then varies it between 100 and 107 so that the
    /// interrupts do not fall into step with the loop.
    const FIRST_RELOAD: u8 = 100;

    /// A flash image: the vector table (SP = [`STACK_TOP`], reset at [`CODE`], SysTick at `systick`, every
    /// other vector at `parked`, a `b .`), the Thumb `code` from [`CODE`] and `literals` from 0x130.
    fn flash_image(code: &[u16], systick: u32, parked: u32, literals: &[u32]) -> Vec<u8> {
        let mut flash = vec![0xFF; 0x1000];
        let mut word = |at: usize, value: u32| flash[at..at + 4].copy_from_slice(&value.to_le_bytes());
        word(0, STACK_TOP);
        for vector in 1..16 {
            word(vector * 4, 0x0800_0000 | parked | 1); // Thumb bit set
        }
        word(4, 0x0800_0000 | CODE as u32 | 1);
        word(15 * 4, 0x0800_0000 | systick | 1);
        for (k, value) in literals.iter().enumerate() {
            word(0x130 + 4 * k, *value);
        }
        for (k, half) in code.iter().enumerate() {
            flash[CODE + 2 * k..CODE + 2 * k + 2].copy_from_slice(&half.to_le_bytes());
        }
        flash
    }

    /// The flash image: vectors (reset, SysTick, the rest parked on a `b .`), then the program.
    fn image() -> Vec<u8> {
        // Thumb-16 encodings (DDI 0403E A7.7), at CODE:
        let code: [u16; 24] = [
            0x480A,                         // 0x100 ldr r0, [pc, #40]   ; =SYST_CSR at 0x12c
            0x2100 | (FIRST_RELOAD as u16), // 0x102 movs r1, #reload
            0x6041,                         // 0x104 str r1, [r0, #4]    ; SYST_RVR
            0x2100,                         // 0x106 movs r1, #0
            0x6081,                         // 0x108 str r1, [r0, #8]    ; SYST_CVR
            0x2400,                         // 0x10a movs r4, #0         ; wrongly executed adds
            0x2500,                         // 0x10c movs r5, #0         ; loop passes
            0x2600,                         // 0x10e movs r6, #0         ; SysTick handler entries
            0x2107,                         // 0x110 movs r1, #7         ; ENABLE | TICKINT | CLKSOURCE
            0x6001,                         // 0x112 str r1, [r0, #0]    ; SYST_CSR
            0x42AD,                         // 0x114 loop: cmp r5, r5    ; Z = 1, so NE fails
            0xBF18,                         // 0x116 it ne
            0x3401,                         // 0x118 addne r4, #1        ; must never execute
            0x3501,                         // 0x11a adds r5, #1
            0xE7FA,                         // 0x11c b loop
            0x3601,                         // 0x11e systick: adds r6, #1 ; flags come back from the frame
            0x2207,                         // 0x120 movs r2, #7
            0x4032,                         // 0x122 ands r2, r6
            0x3264,                         // 0x124 adds r2, #100       ; next period 101..108 cycles, so the
            0x6042,                         // 0x126 str r2, [r0, #4]    ; interrupts land all over the loop
            0x4770,                         // 0x128 bx lr
            0xE7FE,                         // 0x12a parked: b .
            0xE010,                         // 0x12c .word 0xE000E010 (SYST_CSR), low half
            0xE000,                         //       high half
        ];
        flash_image(&code, 0x11E, 0x12A, &[])
    }

    fn register(board: &mut Board, n: usize) -> u32 {
        let target = MachineTarget::new(&mut board.machine);
        let bytes = target.read_register(0, n).expect("the core's registers read");
        u32::from_le_bytes(bytes[..4].try_into().expect("four bytes"))
    }

    /// Runs a loop program for 2 ms at the machine's core clock (about 3 000 SysTick interrupts) and returns
    /// (r4: wrongly executed conditional adds, r5: loop passes, r6: interrupts), after checking the core
    /// stayed inside the program (`pc` in `inside`) and the loop and the interrupts both ran often.
    fn run_loop(image: Vec<u8>, inside: std::ops::Range<u32>) -> (u32, u32, u32) {
        let fitted = Fitted {
            multiranger: false,
            flow: false,
        };
        let mut board = Board::new(image, Faults::default(), fitted).expect("the machine builds");
        board.run_ns(2_000_000).expect("the program runs");
        let (wrong, passes, interrupts, pc) = (
            register(&mut board, 4),
            register(&mut board, 5),
            register(&mut board, 6),
            register(&mut board, 15),
        );
        assert!(inside.contains(&pc), "the core left the program: pc {pc:#x}");
        assert!(
            interrupts > 300 && passes > 1000,
            "SysTick {interrupts} times, {passes} loop passes"
        );
        (wrong, passes, interrupts)
    }

    #[test]
    fn an_interrupt_inside_an_it_block_keeps_its_condition() {
        let (wrong, passes, interrupts) = run_loop(image(), 0x0800_0114..0x0800_012A);
        assert_eq!(
            wrong, 0,
            "`addne` ran {wrong} times with Z set ({interrupts} interrupts, {passes} passes): ITSTATE was lost on \
             an exception"
        );
    }

    /// The FPSCR check's program: the FPU on (CPACR), s0 = −1.0, then a loop that compares s0 with zero
    /// (FPSCR.N = 1), copies the flags to APSR and must skip an `addpl` (N set); SysTick interrupts it every
    /// 101–108 cycles with a handler that uses no floating point (the frame's FP half stays reserved).
    fn fpscr_image() -> Vec<u8> {
        // Assembled with arm-none-eabi-as -mcpu=cortex-m4 (.fpu fpv4-sp-d16), at CODE:
        let code: [u16; 40] = [
            0x4811, 0xF44F, 0x0170, // 0x100 ldr r0, =CPACR; mov.w r1, #0x00F00000 (CP10, CP11 full)
            0x6001, // 0x106 str r1, [r0]
            0xF3BF, 0x8F4F, 0xF3BF, 0x8F6F, // 0x108 dsb; isb
            0xEEBF, 0x0A00, // 0x110 vmov.f32 s0, #-1.0   ; the thread now owns an FP context
            0x480D, // 0x114 ldr r0, =SYST_CSR
            0x2164, 0x6041, // 0x116 movs r1, #100; str r1, [r0, #4] ; SYST_RVR
            0x2100, 0x6081, // 0x11a movs r1, #0; str r1, [r0, #8]   ; SYST_CVR
            0x2400, 0x2500, 0x2600, // 0x11e r4 wrongly executed adds, r5 passes, r6 interrupts
            0x2107, 0x6001, // 0x124 movs r1, #7; str r1, [r0]      ; SYST_CSR: on
            0xEEB5, 0x0A40, // 0x128 loop: vcmp.f32 s0, #0.0      ; FPSCR.N = 1
            0xEEF1, 0xFA10, // 0x12c vmrs APSR_nzcv, fpscr        ; an interrupt just before must not
            0xBF58, //         0x130 it pl                        ; change what this reads
            0x3401, //         0x132 addpl r4, #1                 ; must never execute
            0x3501, 0xE7F7, // 0x134 adds r5, #1; b loop
            0x3601, 0x2207, 0x4032, 0x3264, 0x6042, 0x4770, // 0x138 systick: r6++, reload 101..108, bx lr
            0xE7FE, 0x0000, // 0x144 parked: b .
            0xED88, 0xE000, // 0x148 .word 0xE000ED88 (CPACR)
            0xE010, 0xE000, // 0x14c .word 0xE000E010 (SYST_CSR)
        ];
        flash_image(&code, 0x138, 0x144, &[])
    }

    #[test]
    fn an_interrupt_between_a_vcmp_and_its_vmrs_keeps_the_fpscr_flags() {
        let (wrong, passes, interrupts) = run_loop(fpscr_image(), 0x0800_0128..0x0800_0144);
        assert_eq!(
            wrong, 0,
            "`addpl` ran {wrong} times with FPSCR.N set ({interrupts} interrupts, {passes} passes): the \
             exception entry overwrote the interrupted code's FPSCR flags"
        );
    }

    /// SysTick's reload for the sleep check: a period of 3 000 cycles, longer than a scheduler budget
    /// (`board::QUANTUM_NS` at 168 MHz), so a sleep skip that ran past the wrap would show.
    const SLEEP_RELOAD: u32 = 2_999;
    /// Where the SysTick handler of the sleep check logs `DWT_CYCCNT`, one word per entry.
    const CYCLE_LOG: u32 = 0x2000_0000;

    /// A core that sleeps in `WFI` between SysTick interrupts; the handler appends `DWT_CYCCNT` to
    /// [`CYCLE_LOG`].
    fn sleeping_image() -> Vec<u8> {
        // Thumb-16 encodings (DDI 0403E A7.7); `ldr rT, [pc, #imm]` loads the literals at 0x130.
        let code: [u16; 24] = [
            0x480B, // 0x100 ldr r0, =SYST_CSR
            0x490C, // 0x102 ldr r1, =SLEEP_RELOAD
            0x6041, // 0x104 str r1, [r0, #4]    ; SYST_RVR
            0x2100, // 0x106 movs r1, #0
            0x6081, // 0x108 str r1, [r0, #8]    ; SYST_CVR
            0x4A0B, // 0x10a ldr r2, =DEMCR
            0x490B, // 0x10c ldr r1, =TRCENA
            0x6011, // 0x10e str r1, [r2]
            0x4B0B, // 0x110 ldr r3, =DWT_CTRL
            0x2101, // 0x112 movs r1, #1         ; CYCCNTENA
            0x6019, // 0x114 str r1, [r3]
            0x2600, // 0x116 movs r6, #0         ; SysTick handler entries
            0x4F0A, // 0x118 ldr r7, =CYCLE_LOG
            0x2107, // 0x11a movs r1, #7         ; ENABLE | TICKINT | CLKSOURCE
            0x6001, // 0x11c str r1, [r0]        ; SYST_CSR
            0xBF30, // 0x11e loop: wfi
            0xE7FD, // 0x120 b loop
            0x6859, // 0x122 systick: ldr r1, [r3, #4] ; DWT_CYCCNT
            0x6039, // 0x124 str r1, [r7]
            0x3704, // 0x126 adds r7, #4
            0x3601, // 0x128 adds r6, #1
            0x4770, // 0x12a bx lr
            0xE7FE, // 0x12c parked: b .
            0xBF00, // 0x12e nop (literal alignment)
        ];
        let literals: [u32; 6] = [0xE000_E010, SLEEP_RELOAD, 0xE000_EDFC, 1 << 24, 0xE000_1000, CYCLE_LOG];
        flash_image(&code, 0x122, 0x12C, &literals)
    }

    /// SysTick pends on the clock its counter reaches zero and reloads on the next (DDI 0403E B3.3.1), so
    /// with the core asleep every handler entry is exactly `SLEEP_RELOAD + 1` cycles after the one before,
    /// however the emulator batches the idle cycles.
    #[test]
    fn a_sleeping_core_wakes_on_the_systick_cycle() {
        let fitted = Fitted {
            multiranger: false,
            flow: false,
        };
        let mut board = Board::new(sleeping_image(), Faults::default(), fitted).expect("the machine builds");
        // 2 ms at 168 MHz: about 110 periods.
        board.run_ns(2_000_000).expect("the program runs");
        let entries = register(&mut board, 6);
        assert!(entries > 100, "SysTick ran its handler {entries} times");
        let log: Vec<u32> = (0..entries)
            .map(|k| board.peek32(u64::from(CYCLE_LOG + 4 * k)).expect("RAM reads"))
            .collect();
        let gaps: Vec<u32> = log.windows(2).map(|w| w[1].wrapping_sub(w[0])).collect();
        assert!(
            gaps.iter().all(|&gap| gap == SLEEP_RELOAD + 1),
            "cycles between SysTick handler entries: {gaps:?}"
        );
    }
}
