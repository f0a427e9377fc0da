//! The cfnav firmware for the Crazyflie 2.1 (STM32F405). Embassy wiring only; the logic lives in the library.
//!
//! Build it with `cargo run -p cfnav-tools -- firmware` (or the `cargo fw` alias). On the host this file
//! compiles to a stub that explains that.
//!
//! At this stage the firmware:
//! - clocks the MCU from the 8 MHz HSE through the PLL at 168 MHz (APB1 42 MHz, APB2 84 MHz, PLL-Q 48 MHz), with
//!   the embassy time driver on TIM5 (TIM2/TIM4 drive the motors);
//! - runs a placeholder 1 kHz control tick on an [`InterruptExecutor`] driven by the otherwise unused UART4
//!   interrupt, at NVIC priority [`CONTROL_PRIORITY`]; it counts ticks and records how late each one ran;
//! - runs, in thread mode (the lowest priority), the D* Lite planner on a canned 120 × 60 map, in slices of
//!   [`PLAN_SLICE_EXPANSIONS`] expansions, with the planner's state in CCM; then walks the planned path as a
//!   self-test and logs the cost, the time taken and how the control tick fared meanwhile;
//! - shows the state on the LEDs: booting (blue on, green blinking), ready (planner self-test passed: greens on
//!   with a heartbeat) or fault (reds blinking).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "the cfnav firmware runs on the Crazyflie's STM32F405: build it with \
         `cargo run --release -p cfnav-tools -- firmware` (writes target/cf2.bin)"
    );
    std::process::exit(2);
}

#[cfg(target_os = "none")]
mod fw {
    use core::future::poll_fn;
    use core::mem::MaybeUninit;
    use core::sync::atomic::{AtomicBool, AtomicU8, AtomicU32, Ordering};
    use core::task::Poll;

    use cfnav::dstar::{ArenaPlanner, PlanStatus};
    use cfnav::map::{ARENA_CELLS, Cell, GridShape, Traversability};
    use defmt::{error, info, warn};
    use embassy_executor::{InterruptExecutor, SpawnError, Spawner};
    use embassy_stm32::gpio::{Level, Output, Speed};
    use embassy_stm32::interrupt;
    use embassy_stm32::interrupt::{InterruptExt, Priority};
    use embassy_stm32::{Peri, peripherals};
    use embassy_time::{Duration, Instant, Timer};
    use {defmt_rtt as _, panic_probe as _};

    // ---------------------------------------------------------------------------------------------------------
    // Clocks
    // ---------------------------------------------------------------------------------------------------------

    /// HSE 8 MHz (crazyflie-hardware.md §2) → PLL: /4 = 2 MHz VCO input, ×168 = 336 MHz VCO, /2 = 168 MHz SYSCLK,
    /// /7 = 48 MHz PLL-Q. AHB /1 = 168 MHz, APB1 /4 = 42 MHz, APB2 /2 = 84 MHz (toolchain.md §3.4).
    fn clock_config() -> embassy_stm32::Config {
        use embassy_stm32::rcc::{
            AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv, PllSource, Sysclk,
        };
        use embassy_stm32::time::Hertz;

        let mut config = embassy_stm32::Config::default();
        config.rcc.hse = Some(Hse {
            freq: Hertz(8_000_000),
            mode: HseMode::Oscillator,
        });
        config.rcc.pll_src = PllSource::HSE;
        config.rcc.pll = Some(Pll {
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL168,
            divp: Some(PllPDiv::DIV2),
            divq: Some(PllQDiv::DIV7),
            divr: None,
        });
        config.rcc.ahb_pre = AHBPrescaler::DIV1;
        config.rcc.apb1_pre = APBPrescaler::DIV4;
        config.rcc.apb2_pre = APBPrescaler::DIV2;
        config.rcc.sys = Sysclk::PLL1_P;
        config
    }

    // ---------------------------------------------------------------------------------------------------------
    // Status and LEDs
    // ---------------------------------------------------------------------------------------------------------

    /// What the firmware is doing, as the LEDs show it.
    #[derive(Clone, Copy, PartialEq, Eq, Debug, defmt::Format)]
    #[repr(u8)]
    enum Status {
        /// Initialising; the planner self-test is running.
        Booting = 0,
        /// The planner self-test passed.
        Ready = 1,
        /// Something failed (see the defmt log).
        Fault = 2,
    }

    impl Status {
        fn from_u8(v: u8) -> Self {
            match v {
                0 => Status::Booting,
                1 => Status::Ready,
                _ => Status::Fault,
            }
        }
    }

    static STATUS: AtomicU8 = AtomicU8::new(Status::Booting as u8);

    fn status() -> Status {
        Status::from_u8(STATUS.load(Ordering::Relaxed))
    }

    /// Moves to `next` unless a fault was already recorded: a fault is final.
    fn set_status(next: Status) {
        let _ = STATUS.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |cur| {
            (cur != Status::Fault as u8).then_some(next as u8)
        });
    }

    /// Which of the five STM32-driven LEDs are lit (`true` = light on, whatever the pin polarity).
    #[derive(Clone, Copy, PartialEq, Eq, Debug, defmt::Format)]
    struct LedFrame {
        blue_l: bool,
        green_l: bool,
        red_l: bool,
        green_r: bool,
        red_r: bool,
    }

    /// The LED pattern for a status at `t_ms` milliseconds since boot (pure; the LED task samples it).
    ///
    /// - Booting: blue on, both greens blinking together at 4 Hz.
    /// - Ready: both greens on, with a 100 ms dark heartbeat once a second (shows the thread executor runs).
    /// - Fault: both reds blinking together at 2 Hz, everything else off.
    const fn led_frame(status: Status, t_ms: u64) -> LedFrame {
        const OFF: LedFrame = LedFrame {
            blue_l: false,
            green_l: false,
            red_l: false,
            green_r: false,
            red_r: false,
        };
        match status {
            Status::Booting => {
                let blink = (t_ms / 125).is_multiple_of(2);
                LedFrame {
                    blue_l: true,
                    green_l: blink,
                    green_r: blink,
                    ..OFF
                }
            }
            Status::Ready => {
                let lit = t_ms % 1000 >= 100;
                LedFrame {
                    green_l: lit,
                    green_r: lit,
                    ..OFF
                }
            }
            Status::Fault => {
                let blink = (t_ms / 250).is_multiple_of(2);
                LedFrame {
                    red_l: blink,
                    red_r: blink,
                    ..OFF
                }
            }
        }
    }

    /// The Crazyflie 2.1's STM32-driven LEDs (crazyflie-hardware.md §7, from bitcraze crazyflie-firmware
    /// src/drivers/interface/led.h): BLUE_L on PD2 is active high; GREEN_L PC1, RED_L PC0, GREEN_R PC2 and
    /// RED_R PC3 are active low. The fifth (blue) LED belongs to the nRF51.
    struct Leds {
        blue_l: Output<'static>,
        green_l: Output<'static>,
        red_l: Output<'static>,
        green_r: Output<'static>,
        red_r: Output<'static>,
    }

    impl Leds {
        /// Takes the pins, all LEDs off.
        fn new(
            pd2: Peri<'static, peripherals::PD2>,
            pc1: Peri<'static, peripherals::PC1>,
            pc0: Peri<'static, peripherals::PC0>,
            pc2: Peri<'static, peripherals::PC2>,
            pc3: Peri<'static, peripherals::PC3>,
        ) -> Self {
            Self {
                blue_l: Output::new(pd2, Level::Low, Speed::Low),
                green_l: Output::new(pc1, Level::High, Speed::Low),
                red_l: Output::new(pc0, Level::High, Speed::Low),
                green_r: Output::new(pc2, Level::High, Speed::Low),
                red_r: Output::new(pc3, Level::High, Speed::Low),
            }
        }

        fn show(&mut self, frame: LedFrame) {
            let active_high = |on: bool| if on { Level::High } else { Level::Low };
            let active_low = |on: bool| if on { Level::Low } else { Level::High };
            self.blue_l.set_level(active_high(frame.blue_l));
            self.green_l.set_level(active_low(frame.green_l));
            self.red_l.set_level(active_low(frame.red_l));
            self.green_r.set_level(active_low(frame.green_r));
            self.red_r.set_level(active_low(frame.red_r));
        }
    }

    #[embassy_executor::task]
    async fn led_task(mut leds: Leds) {
        loop {
            leds.show(led_frame(status(), Instant::now().as_millis()));
            Timer::after_millis(25).await;
        }
    }

    // ---------------------------------------------------------------------------------------------------------
    // High-priority control executor
    // ---------------------------------------------------------------------------------------------------------

    /// NVIC priority of the control executor (P0 is the highest; the TIM5 time driver keeps its default P0).
    /// Thread mode, where the planner runs, is below every interrupt.
    const CONTROL_PRIORITY: Priority = Priority::P6;
    /// Control loop period.
    const CONTROL_PERIOD: Duration = Duration::from_hz(1000);

    static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();

    /// Control ticks run since boot.
    static CONTROL_TICKS: AtomicU32 = AtomicU32::new(0);
    /// Worst lateness of a control tick behind its deadline, microseconds.
    static CONTROL_MAX_LATE_US: AtomicU32 = AtomicU32::new(0);

    // The UART4 peripheral is not used (the Crazyflie 2.1's deck UARTs are USART2 and USART3, syslink is USART6:
    // crazyflie-hardware.md §5), so its interrupt vector drives the control executor. Pick another spare vector
    // if UART4 is ever needed.
    #[interrupt]
    fn UART4() {
        // SAFETY: this is the UART4 handler, the only place `on_interrupt` is called, and UART4 is unmasked only
        // by `EXECUTOR_HIGH.start()`, so the executor is initialised whenever this runs.
        unsafe { EXECUTOR_HIGH.on_interrupt() }
    }

    /// Placeholder for estimation + control: counts 1 kHz ticks and records how late they ran.
    #[embassy_executor::task]
    async fn control_task() {
        let mut deadline = Instant::now() + CONTROL_PERIOD;
        loop {
            Timer::at(deadline).await;
            let late_us = Instant::now().saturating_duration_since(deadline).as_micros();
            CONTROL_MAX_LATE_US.fetch_max(u32::try_from(late_us).unwrap_or(u32::MAX), Ordering::Relaxed);
            CONTROL_TICKS.fetch_add(1, Ordering::Relaxed);
            deadline += CONTROL_PERIOD;
        }
    }

    // ---------------------------------------------------------------------------------------------------------
    // Planner self-test on a canned map
    // ---------------------------------------------------------------------------------------------------------

    /// Expansions per planner slice; the thread executor runs its other tasks between slices.
    const PLAN_SLICE_EXPANSIONS: u32 = 500;

    /// A blocked rectangle of cells, `x0..x1 × y0..y1` (ends exclusive).
    struct Rect {
        x0: i32,
        y0: i32,
        x1: i32,
        y1: i32,
    }

    /// The 6 × 3 m seed arena (120 × 60 cells) with two walls, each with a 40 cm gap on opposite sides, and a
    /// box between them. Start on the left, goal on the right: the path must weave up and down.
    struct CannedMap;

    const CANNED_SHAPE: GridShape = GridShape { width: 120, height: 60 };
    const _: () = assert!(120 * 60 <= ARENA_CELLS, "the canned map must fit the planner");
    const CANNED_START: Cell = Cell::new(10, 30);
    const CANNED_GOAL: Cell = Cell::new(110, 30);
    const CANNED_BLOCKS: [Rect; 5] = [
        Rect {
            x0: 40,
            y0: 0,
            x1: 42,
            y1: 38,
        }, // wall 1, gap at y 38..46 (upper half)
        Rect {
            x0: 40,
            y0: 46,
            x1: 42,
            y1: 60,
        },
        Rect {
            x0: 80,
            y0: 0,
            x1: 82,
            y1: 12,
        }, // wall 2, gap at y 12..20 (lower half)
        Rect {
            x0: 80,
            y0: 20,
            x1: 82,
            y1: 60,
        },
        Rect {
            x0: 58,
            y0: 24,
            x1: 64,
            y1: 36,
        }, // box
    ];

    impl Traversability for CannedMap {
        fn shape(&self) -> GridShape {
            CANNED_SHAPE
        }

        fn is_blocked(&self, x: i32, y: i32) -> bool {
            !CANNED_SHAPE.contains(x, y)
                || CANNED_BLOCKS
                    .iter()
                    .any(|r| x >= r.x0 && x < r.x1 && y >= r.y0 && y < r.y1)
        }
    }

    /// The planner's state (≈ 40 KiB), in CCM: CPU-only memory that nothing DMAs from. The section is NOLOAD,
    /// so it holds garbage at reset until [`take_planner`] writes the initial state.
    // SAFETY: `.ccmram` is the NOLOAD output section memory.x places in CCM; the linker lays this static out there
    // like any other, and the only consequence of NOLOAD (no initial value) is handled by `take_planner`.
    #[unsafe(link_section = ".ccmram")]
    static mut PLANNER: MaybeUninit<ArenaPlanner> = MaybeUninit::uninit();
    /// Set once [`PLANNER`] has been handed out (kept in `.bss`, which is zeroed at reset, not in CCM).
    static PLANNER_TAKEN: AtomicBool = AtomicBool::new(false);

    /// Initialises the CCM planner and hands out the only reference to it; `None` on a second call.
    fn take_planner() -> Option<&'static mut ArenaPlanner> {
        if PLANNER_TAKEN.swap(true, Ordering::AcqRel) {
            return None;
        }
        let slot: *mut MaybeUninit<ArenaPlanner> = &raw mut PLANNER;
        // SAFETY: `PLANNER_TAKEN` lets exactly one caller past this point, and `PLANNER` is named nowhere else,
        // so this is the only reference ever made to it; the slot is valid, aligned, 'static storage, and writing
        // a fully initialised value into a `MaybeUninit` is always sound. The initial value is a constant, so it
        // is written in place (a memset when the planner's initial state is all-zero, as `new()` promises).
        Some(unsafe { (*slot).write(const { ArenaPlanner::new() }) })
    }

    /// Walks the planned path from `start` with `next_cell`; returns its number of moves if it reaches `goal`
    /// through free, adjacent cells without looping.
    fn walk_path(planner: &ArenaPlanner, map: &CannedMap, start: Cell, goal: Cell) -> Option<u32> {
        let mut at = start;
        let mut moves = 0u32;
        while at != goal {
            let next = planner.next_cell(map, at)?;
            if next.chebyshev(at) != 1 || map.is_blocked(i32::from(next.x), i32::from(next.y)) {
                return None;
            }
            moves += 1;
            if moves as usize > ARENA_CELLS {
                return None;
            }
            at = next;
        }
        Some(moves)
    }

    /// Yields once to the executor, so the other thread-mode tasks run (the planner is CPU-bound).
    async fn yield_now() {
        let mut yielded = false;
        poll_fn(|cx| {
            if yielded {
                Poll::Ready(())
            } else {
                yielded = true;
                cx.waker().wake_by_ref();
                Poll::Pending
            }
        })
        .await;
    }

    fn fault(what: &str) {
        error!("fault: {}", what);
        STATUS.store(Status::Fault as u8, Ordering::Relaxed);
    }

    #[embassy_executor::task]
    async fn planner_task(planner: &'static mut ArenaPlanner) {
        let map = CannedMap;
        if let Err(e) = planner.reset(map.shape(), CANNED_START, CANNED_GOAL) {
            error!("planner reset: {}", defmt::Debug2Format(&e));
            fault("planner reset failed");
            return;
        }
        let t0 = Instant::now();
        let ticks0 = CONTROL_TICKS.load(Ordering::Relaxed);
        let mut slices = 0u32;
        let cost = loop {
            slices += 1;
            match planner.compute(&map, PLAN_SLICE_EXPANSIONS) {
                Ok(PlanStatus::Incomplete) => yield_now().await,
                Ok(PlanStatus::Found { cost }) => break cost,
                Ok(PlanStatus::NoPath) => {
                    fault("planner found no path on the canned map");
                    return;
                }
                Err(e) => {
                    error!("planner compute: {}", defmt::Debug2Format(&e));
                    fault("planner compute failed");
                    return;
                }
            }
        };
        let elapsed = Instant::now().saturating_duration_since(t0);
        let ticks = CONTROL_TICKS.load(Ordering::Relaxed).wrapping_sub(ticks0);
        let Some(moves) = walk_path(planner, &map, CANNED_START, CANNED_GOAL) else {
            fault("the planned path does not lead to the goal through free cells");
            return;
        };
        info!(
            "planner self-test passed: cost {} over {} moves, {} slices of {} expansions in {} us",
            cost,
            moves,
            slices,
            PLAN_SLICE_EXPANSIONS,
            elapsed.as_micros()
        );
        let late_us = CONTROL_MAX_LATE_US.load(Ordering::Relaxed);
        info!(
            "control ticks during planning: {} in {} ms; worst tick lateness since boot {} us",
            ticks,
            elapsed.as_millis(),
            late_us
        );
        if u64::from(ticks) + 2 < elapsed.as_millis() || late_us > 200 {
            warn!("the control tick fell behind while the planner ran");
        }
        set_status(Status::Ready);
    }

    // ---------------------------------------------------------------------------------------------------------
    // Entry
    // ---------------------------------------------------------------------------------------------------------

    /// Logs a failed spawn and records the fault. Each task has a pool of one and is spawned exactly once, so
    /// `SpawnError::Busy` cannot happen; this keeps the path explicit rather than panicking.
    fn spawn_failed(task: &str, e: SpawnError) {
        error!("spawning {}: {}", task, e);
        fault("task spawn failed");
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let p = embassy_stm32::init(clock_config());
        info!("cfnav firmware {} booting", env!("CARGO_PKG_VERSION"));

        match led_task(Leds::new(p.PD2, p.PC1, p.PC0, p.PC2, p.PC3)) {
            Ok(token) => spawner.spawn(token),
            Err(e) => spawn_failed("led_task", e),
        }

        // The priority must be set before `start()`, which unmasks the interrupt.
        interrupt::UART4.set_priority(CONTROL_PRIORITY);
        let control = EXECUTOR_HIGH.start(interrupt::UART4);
        match control_task() {
            Ok(token) => control.spawn(token),
            Err(e) => spawn_failed("control_task", e),
        }

        let Some(planner) = take_planner() else {
            fault("planner storage already taken");
            return;
        };
        match planner_task(planner) {
            Ok(token) => spawner.spawn(token),
            Err(e) => spawn_failed("planner_task", e),
        }
    }
}
