//! The cfnav firmware for the Crazyflie 2.1 (STM32F405). Embassy wiring only; the logic lives in the library.
//!
//! Build it with `cargo run -p cfnav-tools -- firmware` (or the `cargo fw` alias). On the host this file
//! compiles to a stub that explains that.
//!
//! Boot, in order (the board layer's module documentation has the priorities and the messages):
//! 1. clocks: 8 MHz HSE through the PLL at 168 MHz (APB1 42 MHz, APB2 84 MHz, PLL-Q 48 MHz); the embassy time
//!    driver runs on TIM5 (TIM2/TIM4 drive the motors); the DWT cycle counter is started for the load figures;
//!    then the flash accelerator (prefetch, I- and D-cache: embassy leaves them off; checked, fault if not on);
//! 2. LEDs ("booting"), motors (TIM2/TIM4 PWM, all off), the independent watchdog (fed from the I/O
//!    executor once it runs);
//! 3. the navigator (map + planner) built in CCM;
//! 4. deck I2C1 (guarded: deadlines and bus recovery): the EEPROM config block (radio settings) and the
//!    persistent parameters; syslink on
//!    USART6 with the radio task (settings, battery auto-update; RADIO_READY once booted); then the deck
//!    rangers (so a stuck deck bus cannot delay the radio) and SPI1: the Flow deck's PMW3901;
//! 5. at 1 s after power-on (stock waits as long before touching the IMU) the BMI088 on I2C3, then the
//!    control loop on the gyro data-ready edge (PC14);
//! 6. the mission task and the statistics; "booted": motors may run from now on, RADIO_READY goes out.
//!
//! Any failure before step 6 records a fault: red LEDs, motors off, the mission refuses to start.
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
mod board;

#[cfg(target_os = "none")]
mod fw {
    use core::sync::atomic::Ordering;

    use cfnav::drivers::bmi088::{AccelTrim, Bmi088};
    use cfnav::stack::{FlightConfig, Stabilizer};
    use defmt::{error, info, warn};
    use defmt_rtt as _;
    use embassy_executor::{SendSpawner, SpawnError, SpawnToken, Spawner};
    use embassy_stm32::exti::{self, ExtiInput};
    use embassy_stm32::gpio::{Level, Output, Pull, Speed};
    use embassy_stm32::i2c::{self, I2c};
    use embassy_stm32::interrupt;
    use embassy_stm32::interrupt::InterruptExt;
    use embassy_stm32::spi::{self, Spi};
    use embassy_stm32::time::Hertz;
    use embassy_stm32::usart::{self, Uart};
    use embassy_stm32::wdg::IndependentWatchdog;
    use embassy_stm32::{bind_interrupts, dma, peripherals};
    use embassy_time::{Delay, Instant, Timer};
    use static_cell::StaticCell;

    use crate::board::{
        self, BOOTED, DECK_FLOW2, DECK_MULTIRANGER, DECKS_OK, IO_PRIORITY, control, i2c_bus, leds, mission, motors,
        radio, sensors, system,
    };

    bind_interrupts!(struct Irqs {
        USART6 => usart::InterruptHandler<peripherals::USART6>;
        DMA2_STREAM7 => dma::InterruptHandler<peripherals::DMA2_CH7>;
        DMA2_STREAM1 => dma::InterruptHandler<peripherals::DMA2_CH1>;
        I2C1_EV => i2c::EventInterruptHandler<peripherals::I2C1>;
        I2C1_ER => i2c::ErrorInterruptHandler<peripherals::I2C1>;
        DMA1_STREAM6 => dma::InterruptHandler<peripherals::DMA1_CH6>;
        DMA1_STREAM0 => dma::InterruptHandler<peripherals::DMA1_CH0>;
        I2C3_EV => i2c::EventInterruptHandler<peripherals::I2C3>;
        I2C3_ER => i2c::ErrorInterruptHandler<peripherals::I2C3>;
        DMA1_STREAM4 => dma::InterruptHandler<peripherals::DMA1_CH4>;
        DMA1_STREAM2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
        DMA2_STREAM3 => dma::InterruptHandler<peripherals::DMA2_CH3>;
        DMA2_STREAM0 => dma::InterruptHandler<peripherals::DMA2_CH0>;
        EXTI4 => exti::InterruptHandler<interrupt::typelevel::EXTI4>;
        EXTI15_10 => exti::InterruptHandler<interrupt::typelevel::EXTI15_10>;
    });

    /// HSE 8 MHz (`docs/hardware.md` §1) → PLL: /4 = 2 MHz VCO input, ×168 = 336 MHz VCO, /2 = 168 MHz SYSCLK,
    /// /7 = 48 MHz PLL-Q. AHB /1 = 168 MHz, APB1 /4 = 42 MHz, APB2 /2 = 84 MHz (`docs/hardware.md` §1).
    fn clock_config() -> embassy_stm32::Config {
        use embassy_stm32::rcc::{
            AHBPrescaler, APBPrescaler, Hse, HseMode, Pll, PllMul, PllPDiv, PllPreDiv, PllQDiv, PllSource, Sysclk,
        };

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

    /// The I/O executor (sensors + radio), on the otherwise unused UART5 vector.
    static EXECUTOR_IO: embassy_executor::InterruptExecutor = embassy_executor::InterruptExecutor::new();

    #[interrupt]
    fn UART5() {
        // SAFETY: this is the UART5 handler, the only place `on_interrupt` is called, and UART5 is unmasked only
        // by `EXECUTOR_IO.start()`, so the executor is initialised whenever this runs.
        unsafe { EXECUTOR_IO.on_interrupt() }
    }

    /// Syslink RX DMA ring (in SRAM: DMA cannot reach CCM). 1 Mbaud is 100 bytes per ms; the radio task
    /// drains it at least every 10 ms.
    static SYSLINK_RX_RING: StaticCell<[u8; 1024]> = StaticCell::new();

    /// The time since power-on the stock firmware waits before touching the IMU (`SENSORS_STARTUP_TIME_MS`).
    const SENSORS_STARTUP_MS: u64 = 1000;

    fn spawn_failed(task: &str, e: SpawnError) {
        error!("spawning {}: {}", task, e);
        board::fault("task spawn failed");
    }

    fn spawn<S>(spawner: &Spawner, name: &str, token: Result<SpawnToken<S>, SpawnError>) {
        match token {
            Ok(token) => spawner.spawn(token),
            Err(e) => spawn_failed(name, e),
        }
    }

    fn spawn_send<S: Send>(spawner: &SendSpawner, name: &str, token: Result<SpawnToken<S>, SpawnError>) {
        match token {
            Ok(token) => spawner.spawn(token),
            Err(e) => spawn_failed(name, e),
        }
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let p = embassy_stm32::init(clock_config());
        info!("cfnav firmware {} booting", env!("CARGO_PKG_VERSION"));
        // embassy's clock setup left the flash caches and prefetch off: every CPU figure assumes them on.
        if let Err(acr) = system::enable_flash_accelerator() {
            error!("FLASH_ACR reads {=u32:#x}", acr);
            board::fault("flash accelerator not enabled");
        }

        // The cycle counter for the load and jitter figures.
        match cortex_m::Peripherals::take() {
            Some(mut cp) => {
                cp.DCB.enable_trace();
                cp.DWT.enable_cycle_counter();
            }
            None => warn!("core peripherals already taken: load figures read 0"),
        }

        spawn(
            &spawner,
            "led_task",
            leds::led_task(leds::Leds::new(p.PD2, p.PC1, p.PC0, p.PC2, p.PC3)),
        );
        let motors = match motors::Motors::new(p.TIM2, p.TIM4, p.PA1, p.PB11, p.PA15, p.PB9) {
            Ok(m) => Some(m),
            Err(e) => {
                error!("motor PWM: {}", e);
                board::fault("motor timers not at 8-bit 328 kHz");
                None
            }
        };
        let wdg = IndependentWatchdog::new(p.IWDG, system::WATCHDOG_TIMEOUT_US);

        // The navigator first, while the stack is shallow (today the compiler builds it in place in CCM; the
        // largest stack frame of the image is 13 KB, see BENCHMARKS.md).
        let config = FlightConfig::default();
        let Some(navigator) = mission::take_navigator(&config) else {
            board::fault("navigator: invalid configuration");
            return;
        };

        // The I/O executor: sensors and radio.
        interrupt::UART5.set_priority(IO_PRIORITY);
        let io = EXECUTOR_IO.start(interrupt::UART5);
        // Fed from the I/O executor, which preempts thread mode: no planner slice can delay a feed.
        spawn_send(&io, "watchdog_task", system::watchdog_task(wdg));

        // Deck bus (every transfer under a deadline, with bus recovery): the config block first, the rangers
        // after the syslink is up, so a stuck deck bus cannot keep the radio from starting.
        let mut i2c_config = i2c::Config::default();
        i2c_config.frequency = Hertz(400_000);
        let deck_bus = I2c::new(p.I2C1, p.PB6, p.PB7, p.DMA1_CH6, p.DMA1_CH0, Irqs, i2c_config);
        let mut deck_i2c = i2c_bus::guard(deck_bus, i2c_bus::I2cRecoveryPins::deck(), i2c_bus::DECK_GUARD);
        let settings = sensors::read_radio_settings(&mut deck_i2c).await;
        let stored_params = board::eeprom::read_persistent(&mut deck_i2c).await;

        // Syslink.
        let mut uart_config = usart::Config::default();
        uart_config.baudrate = 1_000_000;
        // RX pulled up as stock (`uart_syslink.c`): an idle line while the nRF boots reads as idle, not as breaks.
        uart_config.rx_pull = Pull::Up;
        match Uart::new(p.USART6, p.PC7, p.PC6, p.DMA2_CH7, p.DMA2_CH1, Irqs, uart_config) {
            Ok(uart) => {
                let (tx, rx) = uart.split();
                let mut rx = rx.into_ring_buffered(SYSLINK_RX_RING.init([0; 1024]));
                // Receive from now on: the nRF's echoes of the boot settings come while they are sent.
                rx.start_uart();
                // PA4: the nRF's RTS, pulled up as stock (high = stop sending).
                let flow = ExtiInput::new(p.PA4, p.EXTI4, Pull::Up, Irqs);
                spawn_send(
                    &io,
                    "radio_task",
                    radio::radio_task(
                        radio::SyslinkUart {
                            tx,
                            rx,
                            flow,
                            frame_tx: cfnav::radio::syslink_tx::FlowTx::new(),
                        },
                        settings,
                        stored_params,
                    ),
                );
            }
            Err(e) => {
                error!("USART6: {}", e);
                board::fault("syslink UART");
            }
        }

        // Both decks' rangers (then the deck task owns the bus).
        let rangers = sensors::bring_up_rangers(&mut deck_i2c).await;
        let rangers_ok = rangers.z.is_some() && rangers.multi.is_some();
        DECK_MULTIRANGER.store(rangers.multi.is_some(), Ordering::Release);
        spawn_send(&io, "deck_task", sensors::deck_task(deck_i2c, rangers));

        // Flow deck on SPI1, chip select PB4 (idle high), mode 0 at ≤ 1.3125 MHz like stock.
        let mut spi_config = spi::Config::default();
        spi_config.frequency = Hertz(1_312_500);
        spi_config.mode = spi::MODE_0;
        let spi = Spi::new(p.SPI1, p.PA5, p.PA7, p.PA6, p.DMA2_CH3, p.DMA2_CH0, Irqs, spi_config);
        let cs = Output::new(p.PB4, Level::High, Speed::VeryHigh);
        let flow = sensors::init_flow(sensors::SpiWithCs::new(spi, cs)).await;
        let flow_ok = flow.is_some();
        DECK_FLOW2.store(flow_ok, Ordering::Release);
        if let Some(flow) = flow {
            spawn_send(&io, "flow_task", sensors::flow_task(flow));
        }
        // The mission needs the flow sensor, the height ranger and all five Multi-ranger beams.
        DECKS_OK.store(flow_ok && rangers_ok, Ordering::Release);
        if !(flow_ok && rangers_ok) {
            warn!("a deck sensor is missing: the mission will refuse to start");
        }
        spawn_send(&io, "stats_task", system::stats_task());

        // The IMU, at the stock start-up time after power-on.
        Timer::at(Instant::from_millis(SENSORS_STARTUP_MS)).await;
        let sensor_bus = I2c::new(p.I2C3, p.PA8, p.PC9, p.DMA1_CH4, p.DMA1_CH2, Irqs, i2c_config);
        let sensor_i2c = i2c_bus::guard(sensor_bus, i2c_bus::I2cRecoveryPins::sensors(), i2c_bus::IMU_GUARD);
        let mut imu = Bmi088::new(sensor_i2c);
        let imu_ok = match imu.init(&mut Delay).await {
            Ok(()) => true,
            Err(e) => {
                error!("BMI088: {}", defmt::Debug2Format(&e));
                board::fault("IMU init failed");
                false
            }
        };
        let drdy = ExtiInput::new(p.PC14, p.EXTI14, Pull::None, Irqs);
        let trim = AccelTrim::from_degrees(settings.calib_roll_deg, settings.calib_pitch_deg);
        match (
            Stabilizer::new(&config, cfnav::mission::MissionParams::SEED.start_m, 0.0),
            motors,
        ) {
            (Ok(stab), Some(motors)) if imu_ok => {
                // The priority must be set before `start()`, which unmasks the interrupt.
                interrupt::UART4.set_priority(control::PRIORITY);
                let ctrl = control::EXECUTOR.start(interrupt::UART4);
                spawn_send(
                    &ctrl,
                    "control_task",
                    control::control_task(stab, imu, trim, drdy, motors),
                );
                board::CONTROL_RUNNING.store(true, Ordering::Release);
            }
            (Err(_), _) => board::fault("stabilizer: invalid configuration"),
            _ => {}
        }

        spawn(&spawner, "mission_task", mission::mission_task(navigator));
        BOOTED.store(true, Ordering::Release);
        info!("booted in {} ms", Instant::now().as_millis());
    }
}
