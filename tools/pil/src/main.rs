//! `cfnav-pil`: processor-in-the-loop. Runs the unmodified cfnav firmware ELF on an emulated Crazyflie 2.1
//! (rsemu's Cortex-M4F and STM32F4 models, `crazyflie21.machine`) and reports what the image does: the status
//! LEDs through the GPIO model, the defmt log from its RTT buffer, FLASH_ACR, watchdog resets, the syslink
//! packets it sends, and its I2C traffic to the BMI088 model.
//!
//! Boot (docs/pil.md): the image boots to "ready". Exit 0 when the LEDs showed the expected
//! status (`--expect`: "ready" by default, "fault" for a fault that must end safe) for a whole second and the
//! IWDG never reset the core, 1 when not within the time limit, 2 on a usage or setup error.
//!
//! Radio (docs/pil.md): the nRF51 end of the syslink (`nrf51.rs`: setting echoes,
//! SYS_NRF_VERSION, the 100 Hz battery/RSSI stream, RADIO_RAW both ways) and, with `--serve [ADDR]`, its radio
//! host as a UDP socket with `cfnav sim --serve`'s framing (`udp_bridge.rs`), so cflib's `udp://` link reaches
//! the image. A served run depends on when datagrams arrive (wall clock): it is not deterministic; its budget
//! can start at the client's first packet (`--serve-seconds`). `--client` (`client.rs`) is a scripted host on
//! virtual time instead (cflib's connect requests, deterministic); `--probe` (`probe.rs`) samples the core's
//! registers and stack at a panic line.
//!
//! Determinism: the machine is a pure function of the image and the options (no host clock reaches it); the
//! report's `fingerprint` hashes the LED samples, the log and the syslink bytes so two runs can be compared.

mod apb8;
mod board;
mod client;
mod core_check;
mod deck;
mod devices;
mod dreq;
mod flow;
mod hover;
mod leds;
mod mission;
mod nrf51;
mod physics;
mod pin;
mod probe;
mod rtt;
mod stuck;
mod track;
mod udp_bridge;
mod verdict;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::Parser;
use serde::Serialize;

use cfnav::radio::syslink::{SyslinkDecoder, encode};
use cfnav::system::status_led::{BoardStatus, LedFrame};
use cfnav_sim::report::{Landing, Track};

use crate::board::{Board, FLASH_ACR, GPIOC_ODR, GPIOD_ODR, RCC_CSR};
use crate::devices::{BusStats, Faults};

#[derive(Parser, Debug)]
#[command(
    name = "cfnav-pil",
    about = "Run the unmodified cfnav firmware ELF on an emulated Crazyflie 2.1"
)]
struct Args {
    /// The firmware ELF (default: $CARGO_TARGET_DIR or target, then thumbv7em-none-eabihf/release/firmware).
    #[arg(long)]
    elf: Option<PathBuf>,
    /// Virtual seconds to run at most (default 4; with --hover H, H + 25; with --mission, 120). Given with
    /// --hover or --mission it caps the run there too, e.g. to watch a refused start for a few seconds only.
    #[arg(long)]
    seconds: Option<f64>,
    /// Keep running after the expected status was seen (until --seconds).
    #[arg(long)]
    no_stop: bool,
    /// The LED status that counts as success: ready, fault, booting, mission_running, battery_low.
    #[arg(long, default_value = "ready")]
    expect: String,
    /// Inject a fault: bmi088-reset-nack (the IMU does not acknowledge its soft reset), sensor-bus-dead
    /// (nothing on I2C3 acknowledges), sensor-bus-stuck[:K|never] / deck-bus-stuck[:K|never] (a slave holds
    /// SDA of I2C3 / I2C1 low from power-on and lets go after K falling SCL edges, 1..=9, default 9, or
    /// never), rts-high (the nRF51 holds its RTS, PA4, high from power-on: "stop sending"), syslink-tx-dead
    /// (USART6's transmit DMA request never rises: every TX DMA transfer hangs),
    /// flow-deck-lost:SECONDS (from that virtual time on the Flow deck answers nothing: the PMW3901's MISO
    /// floats high, its height ranger leaves the deck bus), imu-lost:SECONDS (from that virtual time on the
    /// BMI088 NACKs both its addresses and its INT3 data-ready stops), multiranger-lost:SECONDS (from then on
    /// the Multi-ranger's expander and four rangers leave the deck bus). Repeatable.
    #[arg(long = "fault")]
    faults: Vec<String>,
    /// The nRF51 end stays silent (no echo of the radio settings): a syslink whose radio chip does not answer.
    #[arg(long)]
    silent_nrf: bool,
    /// Serve the radio over UDP: cflib's `udp://ADDR` connects to the image as to `cfnav sim
    /// --serve` (one datagram = one CRTP packet). Implies --no-stop; the run ends after --seconds virtual.
    #[arg(long, num_args = 0..=1, default_missing_value = "127.0.0.1:19850", value_name = "ADDR")]
    serve: Option<String>,
    /// End the run (and write the report) when standard input reaches end of file: a script that started
    /// `--serve` closes the pipe when its client is done.
    #[arg(long)]
    until_stdin_eof: bool,
    /// Write the report as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Print the decoded defmt log as it arrives.
    #[arg(long)]
    log: bool,
    /// A scripted radio host on virtual time instead of UDP (deterministic): `toc` = cflib's connect
    /// requests (link source, version, log reset, both TOCs item by item, every parameter value), each sent
    /// once the last was answered; `toc:N` repeats it N times. Implies --no-stop until it is done.
    #[arg(long, value_name = "SEQUENCE")]
    client: Option<String>,
    /// Virtual ms at which `--client` sends its first request (the nRF queues it until RADIO_READY).
    #[arg(long, default_value_t = 0)]
    client_at_ms: u64,
    /// With --serve: end the run this many virtual seconds after the client's first CRTP packet (a budget
    /// that cflib's wall-clock pacing cannot race; --seconds still caps the whole run).
    #[arg(long, value_name = "S")]
    serve_seconds: Option<f64>,
    /// Model USART6 as rsemu 0.0.7 does: a CPU read of DR takes a byte the receive DMA was due to take (the
    /// cause of a connect stall, kept to show it; docs/pil.md).
    #[arg(long)]
    usart_cpu_steals: bool,
    /// Sample the core's registers and stack (return-address candidates) at the first panic line of the log
    /// and at the end of the run (for `arm-none-eabi-addr2line`).
    #[arg(long)]
    probe: bool,
    /// The Multi-ranger deck is not fitted (it is modelled by default).
    #[arg(long)]
    no_multiranger: bool,
    /// The Flow deck v2 is not fitted (PMW3901 and its VL53L1x).
    #[arg(long)]
    no_flow: bool,
    /// A simulator world file (`worlds/*.toml`): the sensors see it and the motors fly the simulator's body
    /// in it. Without it (and without --hover) the board sits on a bench: a level, motionless
    /// IMU and fixed ranges.
    #[arg(long)]
    world: Option<PathBuf>,
    /// Hover test without cflib: the nRF51 injects `mission.mode` = 1, `mission.hoverTime` = SECONDS,
    /// `mission.height` (the world's) and `mission.start` = 1 after RADIO_READY; the run ends once the drone
    /// has landed (and the image's 10 s load line came) or at --seconds (default SECONDS + 25). Exit 0 when it took off, held the
    /// height for SECONDS and landed, with no watchdog reset. Implies the physics (the default world without
    /// --world).
    #[arg(long, num_args = 0..=1, default_missing_value = "10", value_name = "SECONDS")]
    hover: Option<f32>,
    /// Seed of the sensor noise streams (as `cfnav sim --seed`).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The round trip without cflib: the nRF51 injects `mission.mode` = 0, `mission.height`
    /// (the world's) and `mission.start` = 1; the flight is scored on the truth as `cfnav sim` scores it
    /// (collisions, landings, distance, mission time; `tools/pil/compare_sitl.py` compares the two). The run
    /// ends 1 s after the mission ended with the drone at rest, or at --seconds (default 120). Exit 0 when
    /// it completed. Implies the physics (the default world without --world).
    #[arg(long, conflicts_with = "hover")]
    mission: bool,
    /// With --hover or --mission: a log block of the image's estimate, yaw, downward range and mission state (every 50 ms,
    /// through the emulated radio), printed with the truth (position, yaw, the z-ranger's true range) as
    /// `trace` lines.
    #[arg(long)]
    trace: bool,
    /// With --mission: also write the run in `cfnav sim --json`'s format (docs/formats.md (report format): world, seed,
    /// outcome, reason, mission time, collisions, clearance, landings, distance, virtual and wall time;
    /// `replans` is null, the planner's count stays inside the image), so a script reads both the same way.
    #[arg(long, requires = "mission", value_name = "FILE")]
    sim_json: Option<PathBuf>,
    /// After the run, apply CI's check NAME to its report (src/verdict.rs): print the check's line and exit 0
    /// if it holds, else print the failed assertion and exit 1 (the run's own verdict is part of the checks
    /// whose scenario must also pass on its own).
    #[arg(long, value_name = "NAME", value_parser = clap::builder::PossibleValuesParser::new(verdict::NAMES))]
    check: Option<String>,
    /// Run nothing: compare two boot reports (`--json` files) and exit 0 if their fingerprints and ready
    /// times are equal, else 1.
    #[arg(long, num_args = 2, value_names = ["FIRST", "SECOND"], conflicts_with = "check")]
    same_boot: Option<Vec<PathBuf>>,
    /// With --hover or --mission: write the flight as points (the image's estimate and mission state from the
    /// trace log block, as --trace asks for it, each with the truth at its time stamp) and its score, for
    /// `cfnav pil --plot`, which draws it with `cfnav sim --plot`'s figure. Adds the trace block's radio
    /// traffic, as --trace does.
    #[arg(long, value_name = "FILE")]
    track: Option<PathBuf>,
    /// Run at most this many times faster than real time (virtual seconds per wall second), as `cfnav sim
    /// --serve --speed`; without it the emulator runs as fast as it can (in flight about 0.1× real time).
    #[arg(long, value_name = "X", value_parser = positive_speed)]
    speed: Option<f64>,
}

/// `--speed`: a finite factor above zero.
fn positive_speed(text: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("{text:?} is not a speed factor above 0 (e.g. 1 = real time)")),
    }
}

/// A run in `cfnav sim --json`'s format (docs/formats.md, report format).
#[derive(Debug, Serialize)]
struct SimReport<'a> {
    world: &'a str,
    seed: u64,
    outcome: &'a str,
    reason: Option<&'a str>,
    mission_time_s: Option<f64>,
    collisions: u32,
    min_clearance_m: Option<f32>,
    landings: &'a [Landing],
    replans: Option<u32>,
    distance_m: f64,
    sim_time_s: f64,
    wall_time_s: f64,
    mission_state: Option<u32>,
}

impl<'a> SimReport<'a> {
    fn of(world: &'a str, seed: u64, m: &'a mission::MissionReport, sim_time_s: f64, wall_time_s: f64) -> Self {
        Self {
            world,
            seed,
            outcome: &m.outcome,
            reason: m.reason.as_deref(),
            mission_time_s: m.mission_time_s,
            collisions: m.collisions,
            min_clearance_m: m.min_clearance_m,
            landings: &m.landings,
            replans: None,
            distance_m: m.distance_m,
            sim_time_s,
            wall_time_s,
            mission_state: m.mission_state,
        }
    }
}

#[derive(Debug, Serialize)]
struct Acr {
    raw: u32,
    latency_ws: u32,
    prften: bool,
    icen: bool,
    dcen: bool,
}

#[derive(Debug, Serialize)]
struct Report {
    elf: String,
    /// FNV-1a of the ELF file, to tell images apart.
    elf_fnv: String,
    faults: Vec<String>,
    /// Virtual ms at which `--fault flow-deck-lost` unplugged the deck.
    flow_deck_lost_at_ms: Option<u64>,
    /// Virtual ms at which `--fault imu-lost` silenced the BMI088.
    imu_lost_at_ms: Option<u64>,
    /// Virtual ms at which `--fault multiranger-lost` unplugged the Multi-ranger.
    multiranger_lost_at_ms: Option<u64>,
    /// With the physics: the virtual ms at which the four motor duties last became zero (0 if they never
    /// ran; null if they still run at the end).
    motors_stopped_at_ms: Option<u64>,
    outcome: &'static str,
    ready: bool,
    /// Virtual ms at which the first whole second of "ready" began.
    ready_at_ms: Option<u64>,
    /// The status asked for with `--expect`.
    expected: &'static str,
    /// Virtual ms at which the first whole second of the expected status began.
    expected_at_ms: Option<u64>,
    /// The status the last whole second of LEDs showed, if one.
    final_status: Option<&'static str>,
    /// Each status the LEDs showed and when (the start of its first whole-second window), in order.
    status_timeline: Vec<(u64, &'static str)>,
    virtual_s: f64,
    wall_s: f64,
    acr: Option<Acr>,
    acr_caches_on: bool,
    iwdg_reset_flag: bool,
    /// USART6 SR, CR1, CR3 at the end (RM0090 §30.6).
    usart6_sr_cr1_cr3: [u32; 3],
    /// DMA2 LISR, HISR, then stream 1 (USART6 RX) CR, NDTR and stream 7 (USART6 TX) CR, NDTR (RM0090 §10.5).
    usart6_dma: [u32; 6],
    /// SPI1 CR1, CR2, SR (RM0090 §28.5), then DMA2 stream 0 (SPI1 RX) CR, NDTR and stream 3 (SPI1 TX) CR,
    /// NDTR, and DMA2 LISR (streams 0–3 flags): where a stuck flow read waits.
    spi1_dma: [u32; 8],
    /// GPIOA IDR (PA4 = the nRF's flow control, bit 4).
    gpioa_idr: u32,
    /// The motor PWM compare registers at the end, M1..M4: TIM2 CCR2, CCR4, CCR1 and TIM4 CCR4 (RM0090
    /// §18.4.13–16; the same channels `physics.rs` reads): all zero = motors off.
    motor_ccr: [u32; 4],
    boots_logged: usize,
    faults_logged: Vec<String>,
    log_lines: usize,
    log_errors: usize,
    log_malformed: usize,
    syslink_packets_from_image: Vec<String>,
    imu_bus: BusStats,
    imu_drdy_pulses: u64,
    /// The image's deck flags (`deck.bcMultiranger`, `deck.bcFlow2`) read from its RAM at the end.
    deck_multiranger: Option<bool>,
    deck_flow2: Option<bool>,
    /// The deck bus rangers and expander models.
    deck_bus: deck::DeckStats,
    /// Each ranger's I2C address at the end (front, back, up, left, right, down; null = powered off).
    ranger_addresses: [Option<u8>; 6],
    /// The PMW3901 model's counters.
    flow_sensor: flow::FlowStats,
    /// The stuck-SDA slaves on I2C3 and I2C1 (`--fault sensor-bus-stuck` / `deck-bus-stuck`).
    sensor_bus_sda: stuck::StuckStats,
    deck_bus_sda: stuck::StuckStats,
    /// The world flown in, if the physics ran.
    world: Option<String>,
    /// The hover test's verdict on the truth (`--hover`).
    hover: Option<hover::HoverReport>,
    /// The round trip's score on the truth (`--mission`), in `cfnav sim --json`'s terms.
    mission: Option<mission::MissionReport>,
    /// When the scripted parameter writes went in, virtual ms.
    script_sent_at_ms: Vec<u64>,
    /// The image's load figures from its defmt log (the last "load" line), if one came.
    load: Option<hover::LoadLine>,
    /// The nRF51 end's counters (battery/RSSI stream, RADIO_RAW both ways).
    nrf: nrf51::NrfStats,
    /// The scripted host's counters (`--client`).
    client: Option<client::ClientStats>,
    /// Virtual ms of the served client's first CRTP packet (`--serve`).
    first_request_ms: Option<u64>,
    /// CPU reads of USART6 DR that left the byte to the receive DMA, and (with --usart-cpu-steals) that took it.
    usart6_rx_kept_for_dma: u64,
    usart6_rx_stolen_from_dma: u64,
    /// `--probe` samples.
    probes: Vec<probe::Sample>,
    /// `--track`'s file (written apart from the report).
    #[serde(skip)]
    track: Option<Track>,
    /// UDP datagrams received and sent (`--serve`).
    udp_received: u64,
    udp_sent: u64,
    fingerprint: String,
    log: Vec<rtt::LogLine>,
}

/// FNV-1a, 64 bit: a stable fingerprint of what the run produced.
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= u64::from(x);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

fn default_elf() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| PathBuf::from("target"), PathBuf::from);
    target.join("thumbv7em-none-eabihf/release/firmware")
}

fn parse_faults(names: &[String]) -> Result<Faults> {
    let mut f = Faults::default();
    for n in names {
        match n.as_str() {
            "bmi088-reset-nack" => f.bmi088_reset_nack = true,
            "sensor-bus-dead" => f.sensor_bus_dead = true,
            "rts-high" => f.rts_high = true,
            "syslink-tx-dead" => f.syslink_tx_dead = true,
            other => {
                let (name, arg) = other.split_once(':').map_or((other, None), |(n, a)| (n, Some(a)));
                let release = || stuck::Release::parse(arg).map_err(|e| anyhow::anyhow!("--fault {name}: {e}"));
                match name {
                    "sensor-bus-stuck" => f.sensor_bus_stuck = Some(release()?),
                    "deck-bus-stuck" => f.deck_bus_stuck = Some(release()?),
                    "flow-deck-lost" | "imu-lost" | "multiranger-lost" => {
                        let at_s = arg
                            .and_then(|a| a.parse::<f64>().ok())
                            .filter(|s| s.is_finite() && (0.0..=3600.0).contains(s))
                            .with_context(|| format!("--fault {other}: give the time in seconds, e.g. {name}:5"))?;
                        let at_ms = Some((at_s * 1000.0).round() as u64);
                        match name {
                            "imu-lost" => f.imu_lost_at_ms = at_ms,
                            "multiranger-lost" => f.multiranger_lost_at_ms = at_ms,
                            _ => f.flow_deck_lost_at_ms = at_ms,
                        }
                    }
                    _ => bail!(
                        "unknown fault `{other}` (known: bmi088-reset-nack, sensor-bus-dead, rts-high, syslink-tx-dead, \
                         sensor-bus-stuck[:K|never], deck-bus-stuck[:K|never], flow-deck-lost:SECONDS, imu-lost:SECONDS, \
                         multiranger-lost:SECONDS)"
                    ),
                }
            }
        }
    }
    Ok(f)
}

fn parse_status(name: &str) -> Result<BoardStatus> {
    [
        BoardStatus::Booting,
        BoardStatus::Ready,
        BoardStatus::MissionRunning,
        BoardStatus::LowBattery,
        BoardStatus::Fault,
    ]
    .into_iter()
    .find(|&s| leds::name(s) == name)
    .with_context(|| format!("unknown --expect `{name}` (known: booting, ready, mission_running, battery_low, fault)"))
}

fn run(args: &Args) -> Result<(Report, bool)> {
    if args
        .hover
        .is_some_and(|h| !(h.is_finite() && (1.0..=60.0).contains(&h)))
    {
        bail!("--hover SECONDS must be in [1, 60]");
    }
    let mut physics = if args.world.is_some() || args.hover.is_some() || args.mission {
        let world = match &args.world {
            Some(p) => cfnav_sim::world::World::load(p).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?,
            None => cfnav_sim::world::World::default_world(),
        };
        Some(physics::Physics::new(world, args.seed))
    } else {
        None
    };
    let mut script = args.hover.map(|h| {
        let height = physics.as_ref().map_or(0.5, |p| p.world.mission.height);
        hover::Script::hover(h, height)
    });
    if let (true, Some(p)) = (args.mission, physics.as_ref()) {
        script = Some(hover::Script::round_trip(&p.world));
    }
    if args.trace || args.track.is_some() {
        script = script.map(hover::Script::with_trace);
    }
    if args.track.is_some() && script.is_none() {
        bail!("--track needs --hover or --mission (a flight to draw)");
    }
    let mut track = args.track.is_some().then(track::TrackRecorder::default);
    let mut mission_judge = args.mission.then(mission::MissionJudge::new);
    let mut mission_done_at_ns: Option<u64> = None;
    let mut judge = args.hover.map(|h| {
        let height = physics.as_ref().map_or(0.5, |p| p.world.mission.height);
        hover::HoverJudge::new(height, h)
    });
    let mut load = None;
    if !args.seconds.is_none_or(|s| s > 0.0 && s <= 600.0) {
        bail!("--seconds must be in (0, 600]");
    }
    let faults = parse_faults(&args.faults)?;
    let expected = parse_status(&args.expect)?;
    let elf_path = args.elf.clone().unwrap_or_else(default_elf);
    let elf = std::fs::read(&elf_path).with_context(|| {
        format!(
            "reading {} (build it with `cargo run --release -p cfnav-tools -- firmware`)",
            elf_path.display()
        )
    })?;
    let image = board::load_image(&elf)?;
    let table = defmt_decoder::Table::parse(&elf)
        .context("reading the .defmt table")?
        .context("the ELF has no .defmt table")?;
    let rtt_address = image.rtt_address.context("the ELF has no _SEGGER_RTT symbol")?;
    let fitted = deck::Fitted {
        multiranger: !args.no_multiranger,
        flow: !args.no_flow,
    };
    let mut board = Board::new(image.flash.clone(), faults, fitted)?;
    board.nrf_rts.set(faults.rts_high);
    let mut nrf = nrf51::Nrf51::new(args.silent_nrf);
    let mut bridge = match &args.serve {
        Some(addr) => {
            let b = udp_bridge::UdpBridge::bind(addr)?;
            println!(
                "serving CRTP on udp://{} (the emulated image; cflib connects once the image sent RADIO_READY)",
                b.local_addr().map_or_else(|| addr.clone(), |a| a.to_string())
            );
            Some(b)
        }
        None => None,
    };
    let mut rtt = rtt::Rtt::new(rtt_address, &table);
    let mut client = match &args.client {
        Some(spec) => Some(client::Client::new(spec, args.client_at_ms).map_err(anyhow::Error::msg)?),
        None => None,
    };
    let mut first_request_ms: Option<u64> = None;
    apb8::set_usart_cpu_steals(args.usart_cpu_steals);
    let mut probes = Vec::new();

    let stdin_closed = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    if args.until_stdin_eof {
        let flag = std::sync::Arc::clone(&stdin_closed);
        std::thread::spawn(move || {
            let _ = std::io::copy(&mut std::io::stdin().lock(), &mut std::io::sink());
            flag.store(true, std::sync::atomic::Ordering::Release);
        });
    }
    let wall = Instant::now();
    let step_ns = 1_000_000u64;
    // A hover run needs the boot and the start (≈ 1.8 s), the take-off (≈ 2.2 s), the hold, the search for the
    // take-off pad's edges (SITL: ≈ 8 s on the default world, more with bad luck), the approach and the landing
    // (≈ 3 s): at least SECONDS + 25 s. (+ 15 s cut the default world's search short: docs/pil.md.)
    let seconds = match args.hover {
        Some(h) => args.seconds.unwrap_or(f64::from(h) + 25.0),
        None if args.mission => args.seconds.unwrap_or(120.0),
        None => args.seconds.unwrap_or(4.0),
    };
    let end_ns = (seconds * 1e9) as u64;
    let mut samples: std::collections::VecDeque<(u64, LedFrame)> = Default::default();
    let mut timeline: Vec<(u64, &'static str)> = Vec::new();
    let mut ready_at_ms = None;
    let mut expected_at_ms = None;
    let mut final_status = None;
    let mut fp = Fnv::new();
    let mut decoder = SyslinkDecoder::new();
    let mut from_image = Vec::new();
    let mut out = [0u8; cfnav::radio::syslink::MAX_FRAME];
    let pulse_ns = 50_000u64;
    let mut drdy_pulses = 0u64;
    let mut last_ms = u64::MAX;
    let mut landed_at_ns: Option<u64> = None;
    let mut flow_deck_lost_at_ms: Option<u64> = None;
    let mut imu_lost_at_ms: Option<u64> = None;
    let mut multiranger_lost_at_ms: Option<u64> = None;
    // When the four duties last became zero (None while they run).
    let mut motors_stopped_at_ms: Option<u64> = Some(0);
    while board.now_ns() < end_ns && !served_budget_spent(args, first_request_ms, board.now_ns()) {
        if let Some(x) = args.speed {
            // Ahead of X × real time: wait for the wall clock (virtual time never waits for the host).
            let due = std::time::Duration::from_secs_f64(board.now_ns() as f64 * 1e-9 / x);
            if let Some(wait) = due.checked_sub(wall.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        board.deck.advance(board.now_ns());
        if let Some(p) = physics.as_mut() {
            p.sensors_out(&board);
            nrf.vbat_v = p.battery_v();
        }
        // The gyroscope's data-ready pulse on INT3 at its ODR (1 kHz as the image configures it), once the
        // firmware has enabled and mapped it; the physics steps in the same slices.
        let slice_ns = if board.imu.int3_drdy_enabled() {
            let period = board.imu.gyro_period_ns();
            board.imu_int3.set(true);
            board.run_ns(pulse_ns)?;
            board.imu_int3.set(false);
            board.run_ns(period - pulse_ns)?;
            drdy_pulses += 1;
            period
        } else {
            board.run_ns(step_ns)?;
            step_ns
        };
        if let Some(p) = physics.as_mut() {
            p.step_to(&board, board.now_ns());
            let t_ns = board.now_ns();
            if let Some(tr) = track.as_mut() {
                tr.truth(t_ns, p.quad.position(), !p.quad.on_ground());
            }
            let stopped = p.duty.0 == [0; 4];
            if !stopped {
                motors_stopped_at_ms = None;
            } else if motors_stopped_at_ms.is_none() {
                motors_stopped_at_ms = Some(t_ns / 1_000_000);
            }
            if args.log && t_ns % 250_000_000 < slice_ns {
                let pos = p.quad.position();
                let att = p.quad.attitude_rad();
                println!(
                    "{:>9.3} | truth x {:.3} y {:.3} z {:.3} roll {:.1} pitch {:.1} yaw {:.1} deg, duty {:?}, vbat {:.2}",
                    t_ns as f64 / 1e9,
                    pos[0],
                    pos[1],
                    pos[2],
                    att[0].to_degrees(),
                    att[1].to_degrees(),
                    att[2].to_degrees(),
                    p.duty.0,
                    p.battery_v()
                );
            }
            if let Some(j) = mission_judge.as_mut() {
                j.sample(
                    &p.world,
                    board.now_ns() as f64 * 1e-9,
                    p.quad.position(),
                    p.quad.on_ground(),
                    p.duty,
                );
            }
            if let Some(j) = judge.as_mut() {
                j.sample(
                    board.now_ns() as f64 * 1e-9,
                    p.quad.position(),
                    p.quad.on_ground(),
                    p.duty,
                );
            }
        }
        let t_ms = board.now_ns() / 1_000_000;
        if faults.flow_deck_lost_at_ms.is_some_and(|at| t_ms >= at) && flow_deck_lost_at_ms.is_none() {
            board.flow.unplug();
            board.deck.unplug_flow();
            flow_deck_lost_at_ms = Some(t_ms);
            if args.log {
                println!("{:>9.3} | fault: the Flow deck stops answering", t_ms as f64 / 1e3);
            }
        }
        if faults.imu_lost_at_ms.is_some_and(|at| t_ms >= at) && imu_lost_at_ms.is_none() {
            board.imu.lose();
            imu_lost_at_ms = Some(t_ms);
            if args.log {
                println!("{:>9.3} | fault: the BMI088 stops answering", t_ms as f64 / 1e3);
            }
        }
        if faults.multiranger_lost_at_ms.is_some_and(|at| t_ms >= at) && multiranger_lost_at_ms.is_none() {
            board.deck.unplug_multiranger();
            multiranger_lost_at_ms = Some(t_ms);
            if args.log {
                println!(
                    "{:>9.3} | fault: the Multi-ranger deck stops answering",
                    t_ms as f64 / 1e3
                );
            }
        }
        board.sensors_sda.tick(t_ms);
        board.deck_sda.tick(t_ms);
        let pins = leds::Pins {
            gpioc_moder: board.peek32(GPIOC_ODR - 0x14).unwrap_or(0),
            gpioc_odr: board.peek32(GPIOC_ODR).unwrap_or(0),
            gpiod_moder: board.peek32(GPIOD_ODR - 0x14).unwrap_or(0),
            gpiod_odr: board.peek32(GPIOD_ODR).unwrap_or(0),
        };
        let frame = leds::frame(pins);
        fp.bytes(&[
            u8::from(frame.blue_l),
            u8::from(frame.green_l),
            u8::from(frame.red_l),
            u8::from(frame.green_r),
            u8::from(frame.red_r),
        ]);
        samples.push_back((t_ms, frame));
        while samples.front().is_some_and(|&(t, _)| t + leds::WINDOW_MS <= t_ms) {
            samples.pop_front();
        }
        // The LED task redraws every 25 ms: classifying every 25th sample sees every change.
        let new_ms = t_ms != last_ms;
        last_ms = t_ms;
        if new_ms && t_ms % 25 == 0 {
            let window: Vec<_> = samples.iter().copied().collect();
            final_status = leds::classify(&window);
            if let Some(s) = final_status {
                let start = window[0].0;
                if timeline.last().map(|&(_, n)| n) != Some(leds::name(s)) {
                    timeline.push((start, leds::name(s)));
                }
                if s == BoardStatus::Ready && ready_at_ms.is_none() {
                    ready_at_ms = Some(start);
                }
                if s == expected && expected_at_ms.is_none() {
                    expected_at_ms = Some(start);
                }
            }
        }
        for line in rtt.poll(&board) {
            fp.bytes(line.text.as_bytes());
            if args.probe && probes.is_empty() && line.text.contains("panicked") {
                probes.extend(probe_sample(&mut board, &line.text));
            }
            if let Some(l) = hover::LoadLine::parse(&line.text) {
                load = Some(l);
            }
            if let Some(j) = judge.as_mut() {
                j.log_line(line.read_at_ns as f64 * 1e-9, &line.text);
            }
            if let Some(j) = mission_judge.as_mut() {
                j.log_line(&line.text);
            }
            if args.log {
                println!("{:>9.3} | {}", line.read_at_ns as f64 / 1e9, line.text);
            }
        }
        let sent = board.syslink.drain();
        fp.bytes(&sent);
        let now_ns = board.now_ns();
        for b in sent {
            if let Some(Ok(packet)) = decoder.push(b) {
                from_image.push(format!("{:#04x}", packet.kind));
                let was_ready = nrf.stats.radio_ready_at_ms.is_some();
                let (back, to_host) = nrf.on_image_packet(&packet, now_ns);
                if let (Some(tr), Some(t)) = (track.as_mut(), to_host.as_deref().and_then(hover::TraceSample::parse)) {
                    tr.sample(&t);
                }
                if let (false, Some(t), Some(_)) = (was_ready, nrf.stats.radio_ready_at_ms, bridge.as_ref()) {
                    println!("radio ready at {t} ms virtual: the nRF's receiver is on");
                }
                for answer in back {
                    if let Ok(n) = encode(&answer, &mut out) {
                        board.syslink.feed(&out[..n]);
                    }
                }
                if let (true, Some(t), Some(p)) = (
                    args.trace,
                    to_host.as_deref().and_then(hover::TraceSample::parse),
                    physics.as_ref(),
                ) {
                    let pos = p.quad.position();
                    let yaw = p.quad.attitude_rad()[2].to_degrees();
                    let down = p.down_range_m().map_or(-1.0, |m| m * 1000.0);
                    println!(
                        "{:>9.3} | trace image t {} ms state {} est x {:.3} y {:.3} z {:.3} yaw {:.1} zrange {} mm | truth x {:.3} y {:.3} z {:.3} yaw {:.1} down {:.0} mm",
                        now_ns as f64 / 1e9,
                        t.at_ms,
                        t.mission_state,
                        t.position_m[0],
                        t.position_m[1],
                        t.position_m[2],
                        t.yaw_deg,
                        t.zrange_mm,
                        pos[0],
                        pos[1],
                        pos[2],
                        yaw,
                        down
                    );
                }
                if let (Some(crtp), Some(bridge)) = (to_host.as_ref(), bridge.as_mut()) {
                    bridge.send(crtp);
                }
                if let (Some(crtp), Some(c)) = (to_host, client.as_mut()) {
                    c.on_downlink(&crtp, now_ns / 1_000_000);
                }
            }
        }
        if let Some(bridge) = bridge.as_mut() {
            for crtp in bridge.receive() {
                first_request_ms.get_or_insert(now_ns / 1_000_000);
                nrf.host_packet(&crtp);
            }
        }
        if let Some(p) = client.as_mut().and_then(|c| c.poll(now_ns / 1_000_000)) {
            nrf.host_packet(&p);
        }
        let ready_ns = nrf.stats.radio_ready_at_ms.map(|ms| ms * 1_000_000);
        if let Some(s) = script.as_mut() {
            for crtp in s.due(now_ns, ready_ns) {
                nrf.host_packet(&crtp);
            }
        }
        let polling = bridge.as_ref().is_some_and(udp_bridge::UdpBridge::has_client)
            || client.as_ref().is_some_and(|c| c.stats.sent > 0)
            || script.as_ref().is_some_and(|s| s.polling(now_ns));
        for packet in nrf.tick(now_ns, polling) {
            if let Ok(n) = encode(&packet, &mut out) {
                board.syslink.feed(&out[..n]);
            }
        }
        if stdin_closed.load(std::sync::atomic::Ordering::Acquire) {
            break;
        }
        if let Some(j) = mission_judge.as_ref() {
            // The mission run ends 1 s after the mission ended with the drone at rest.
            if j.done() {
                if now_ns >= *mission_done_at_ns.get_or_insert(now_ns) + 1_000_000_000 {
                    break;
                }
            } else {
                mission_done_at_ns = None;
            }
            continue;
        }
        if let Some(j) = judge.as_ref() {
            // The hover run ends 1 s after the landing once the image's load line came (or at --seconds).
            if j.landed() {
                let t = *landed_at_ns.get_or_insert(now_ns);
                if load.is_some() && now_ns >= t + 1_000_000_000 {
                    break;
                }
            }
            continue;
        }
        if expected_at_ms.is_some()
            && !args.no_stop
            && args.serve.is_none()
            && client.as_ref().is_none_or(|c| c.stats.done)
        {
            break;
        }
    }
    if let Some(c) = client.as_mut() {
        c.finish();
    }
    if args.probe {
        probes.extend(probe_sample(&mut board, "end of run"));
    }
    let acr = board.peek32(FLASH_ACR).map(|raw| Acr {
        raw,
        latency_ws: raw & 0xF,
        prften: raw & (1 << 8) != 0,
        icen: raw & (1 << 9) != 0,
        dcen: raw & (1 << 10) != 0,
    });
    let acr_caches_on = acr.as_ref().is_some_and(|a| a.icen && a.dcen);
    let iwdg_reset_flag = board.peek32(RCC_CSR).is_some_and(|v| v & (1 << 29) != 0);
    let log = rtt.lines.clone();
    let boots_logged = log.iter().filter(|l| l.text.contains("booting")).count();
    let faults_logged = log
        .iter()
        .filter(|l| l.text.contains("fault: "))
        .map(|l| l.text.clone())
        .collect();
    let ready = ready_at_ms.is_some();
    let hover_report = judge.map(hover::HoverJudge::finish);
    let mission_report = match (mission_judge, physics.as_ref()) {
        (Some(j), Some(p)) => Some(j.finish(&p.world)),
        _ => None,
    };
    let passed = match (&hover_report, &mission_report) {
        (_, Some(m)) => m.passed && !iwdg_reset_flag,
        (Some(h), _) => h.passed && !iwdg_reset_flag,
        (None, None) => expected_at_ms.is_some() && !iwdg_reset_flag && client.as_ref().is_none_or(|c| c.stats.done),
    };
    let track = match (track, physics.as_ref()) {
        (Some(tr), Some(p)) => Some(track_file(
            args,
            tr,
            p,
            hover_report.as_ref(),
            mission_report.as_ref(),
            board.now_ns(),
            wall,
        )),
        _ => None,
    };
    let report = Report {
        elf: elf_path.display().to_string(),
        elf_fnv: {
            let mut h = Fnv::new();
            h.bytes(&elf);
            format!("{:016x}", h.0)
        },
        faults: args.faults.clone(),
        flow_deck_lost_at_ms,
        imu_lost_at_ms,
        multiranger_lost_at_ms,
        motors_stopped_at_ms: physics.as_ref().and(motors_stopped_at_ms),
        outcome: if ready { "ready" } else { "not_ready" },
        ready,
        ready_at_ms,
        expected: leds::name(expected),
        expected_at_ms,
        final_status: final_status.map(leds::name),
        status_timeline: timeline,
        virtual_s: board.now_ns() as f64 / 1e9,
        wall_s: wall.elapsed().as_secs_f64(),
        acr,
        acr_caches_on,
        iwdg_reset_flag,
        usart6_sr_cr1_cr3: [0x00, 0x0C, 0x14].map(|off| board.peek32(0x4001_1400 + off).unwrap_or(0)),
        usart6_dma: [0x00, 0x04, 0x10 + 0x18, 0x14 + 0x18, 0x10 + 0x18 * 7, 0x14 + 0x18 * 7]
            .map(|off| board.peek32(0x4002_6400 + off).unwrap_or(0)),
        spi1_dma: [
            board.peek32(0x4001_3000).unwrap_or(0),
            board.peek32(0x4001_3004).unwrap_or(0),
            board.peek32(0x4001_3008).unwrap_or(0),
            board.peek32(0x4002_6410).unwrap_or(0),
            board.peek32(0x4002_6414).unwrap_or(0),
            board.peek32(0x4002_6410 + 0x18 * 3).unwrap_or(0),
            board.peek32(0x4002_6414 + 0x18 * 3).unwrap_or(0),
            board.peek32(0x4002_6400).unwrap_or(0),
        ],
        gpioa_idr: board.peek32(0x4002_0010).unwrap_or(0),
        motor_ccr: [0x4000_0038, 0x4000_0040, 0x4000_0034, 0x4000_0840].map(|a| board.peek32(a).unwrap_or(0)),
        boots_logged,
        faults_logged,
        log_lines: log.len(),
        log_errors: log.iter().filter(|l| l.level.as_deref() == Some("error")).count(),
        log_malformed: rtt.malformed,
        syslink_packets_from_image: from_image,
        imu_bus: board.imu.stats(),
        imu_drdy_pulses: drdy_pulses,
        deck_multiranger: read_flag(&board, &image.statics, "DECK_MULTIRANGER"),
        deck_flow2: read_flag(&board, &image.statics, "DECK_FLOW2"),
        deck_bus: board.deck.stats(),
        ranger_addresses: board.deck.addresses(),
        flow_sensor: board.flow.stats(),
        sensor_bus_sda: board.sensors_sda.stats(),
        deck_bus_sda: board.deck_sda.stats(),
        world: physics.as_ref().map(|_| {
            args.world
                .as_ref()
                .map_or_else(|| "default".to_string(), |p| p.display().to_string())
        }),
        hover: hover_report,
        mission: mission_report,
        script_sent_at_ms: script.map(|s| s.sent_at_ms).unwrap_or_default(),
        load,
        nrf: nrf.stats.clone(),
        client: client.map(|c| c.stats),
        first_request_ms,
        usart6_rx_kept_for_dma: apb8::USART_RX_KEPT.load(std::sync::atomic::Ordering::Relaxed),
        usart6_rx_stolen_from_dma: apb8::USART_RX_STOLEN.load(std::sync::atomic::Ordering::Relaxed),
        probes,
        track,
        udp_received: bridge.as_ref().map_or(0, |b| b.received),
        udp_sent: bridge.as_ref().map_or(0, |b| b.sent),
        fingerprint: format!("{:016x}", fp.0),
        log,
    };
    Ok((report, passed))
}

/// `--track`'s file: the points, and the score of the hover (its landing judged against the pad under the
/// last truth point) or of the round trip (the mission judge's).
fn track_file(
    args: &Args,
    tr: track::TrackRecorder,
    p: &physics::Physics,
    hover: Option<&hover::HoverReport>,
    mission: Option<&mission::MissionReport>,
    now_ns: u64,
    wall: Instant,
) -> Track {
    let landing = |pad: usize, error_m: f32, on_pad: bool| Landing { pad, error_m, on_pad };
    let mut file = Track {
        world_path: args.world.as_ref().map(|w| w.display().to_string()),
        world: p.world.name.clone(),
        seed: args.seed,
        mode: if mission.is_some() { "round_trip" } else { "hover" }.into(),
        outcome: "timeout".into(),
        reason: None,
        mission_time_s: None,
        mission_state: None,
        collisions: 0,
        min_clearance_m: None,
        landings: Vec::new(),
        distance_m: 0.0,
        virtual_s: now_ns as f64 * 1e-9,
        wall_s: wall.elapsed().as_secs_f64(),
        points: Vec::new(),
    };
    if let Some(m) = mission {
        file.outcome = m.outcome.clone();
        file.reason = m.reason.clone();
        file.mission_time_s = m.mission_time_s;
        file.mission_state = m.mission_state;
        file.collisions = m.collisions;
        file.min_clearance_m = m.min_clearance_m;
        file.landings = m.landings.clone();
        file.distance_m = m.distance_m;
    } else if let Some(h) = hover {
        file.mission_state = h.mission_end_state;
        if h.landed {
            let at = p.quad.position();
            let (pad, on_pad) = p.world.landing_pad_at(at[0], at[1]);
            let c = p.world.pads.get(pad).map_or([at[0], at[1]], |pd| pd.center);
            file.landings
                .push(landing(pad, (at[0] - c[0]).hypot(at[1] - c[1]), on_pad));
        }
        // The simulator's words for the end state (a hover completes on the take-off pad, home).
        let on_home_pad = file.landings.last().is_some_and(|l| l.on_pad && l.pad == 0);
        let (outcome, reason) = mission::outcome_and_reason(0, h.mission_end_state, on_home_pad);
        file.outcome = outcome.into();
        file.reason = reason.map(Into::into);
    }
    file.distance_m = if mission.is_some() {
        file.distance_m
    } else {
        tr.points
            .windows(2)
            .filter(|w| w[1].airborne)
            .map(|w| f64::from((w[1].truth[0] - w[0].truth[0]).hypot(w[1].truth[1] - w[0].truth[1])))
            .sum()
    };
    file.points = tr.points;
    file
}

/// One `--probe` sample, printed as it is taken.
fn probe_sample(board: &mut Board, why: &str) -> Option<probe::Sample> {
    let at_ms = board.now_ns() / 1_000_000;
    let mut s = probe::sample(&mut board.machine, at_ms, why, 0x0800_4000..0x0810_0000)?;
    // DMA1 (I2C1/I2C3 streams 0, 2, 4, 6: CR, NDTR, PAR, M0AR) and, with CFNAV_PIL_DUMP=DIR, the whole SRAM
    // (.data, .bss and the stack) to DIR/ram-MS.bin, for reading by hand.
    for stream in [0u64, 2, 4, 6] {
        let at = 0x4002_6010 + 0x18 * stream;
        let regs: Vec<String> = (0..4)
            .map(|k| format!("{:#x}", board.peek32(at + 4 * k).unwrap_or(0)))
            .collect();
        s.stack_code.push(format!("dma1.s{stream}={}", regs.join("/")));
    }
    if let Ok(dir) = std::env::var("CFNAV_PIL_DUMP") {
        let words: Vec<u32> = (0x2000_0000u64..0x2002_0000)
            .step_by(4)
            .map(|a| board.peek32(a).unwrap_or(0))
            .collect();
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        let _ = std::fs::write(format!("{dir}/ram-{at_ms}.bin"), bytes);
    }
    println!(
        "probe at {at_ms} ms ({why}): pc={} lr={} sp={}; stack code: {}; stack words: {}",
        s.regs[15],
        s.regs[14],
        s.regs[13],
        s.stack_code.join(" "),
        s.stack_words.join(" ")
    );
    Some(s)
}

/// `--serve-seconds`: the served run's virtual budget, counted from the client's first CRTP packet, is spent.
fn served_budget_spent(args: &Args, first_request_ms: Option<u64>, now_ns: u64) -> bool {
    match (args.serve_seconds, first_request_ms) {
        (Some(s), Some(t0)) => now_ns >= t0 * 1_000_000 + (s * 1e9) as u64,
        _ => false,
    }
}

/// An `AtomicBool` static of the image, by its symbol substring.
fn read_flag(board: &Board, statics: &[(&'static str, u64)], name: &str) -> Option<bool> {
    let &(_, addr) = statics.iter().find(|(n, _)| *n == name)?;
    board.peek8(addr).map(|b| b != 0)
}

fn main() -> ExitCode {
    let args = Args::parse();
    if let Some(paths) = &args.same_boot {
        return match verdict::same_boot(&paths[0], &paths[1]) {
            Ok(line) => {
                println!("same boot: {line}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("same boot failed: {e}");
                ExitCode::from(1)
            }
        };
    }
    match run(&args) {
        Ok((report, passed)) => {
            println!(
                "outcome={} ready_at_ms={} expected={} expected_at_ms={} final_status={} virtual_s={:.3} wall_s={:.2} acr_caches_on={} \
                 acr_latency_ws={} iwdg_reset_flag={} boots_logged={} log_lines={} log_errors={} \
                 imu_soft_resets={} imu_nacked_bytes={} syslink_packets={} deck_multiranger={} deck_flow2={} fingerprint={}",
                report.outcome,
                report.ready_at_ms.map_or_else(|| "-".to_string(), |t| t.to_string()),
                report.expected,
                report.expected_at_ms.map_or_else(|| "-".to_string(), |t| t.to_string()),
                report.final_status.unwrap_or("-"),
                report.virtual_s,
                report.wall_s,
                report.acr_caches_on,
                report.acr.as_ref().map_or(0, |a| a.latency_ws),
                report.iwdg_reset_flag,
                report.boots_logged,
                report.log_lines,
                report.log_errors,
                report.imu_bus.soft_resets,
                report.imu_bus.nacked_bytes,
                report.syslink_packets_from_image.len(),
                report.deck_multiranger.map_or(-1, i32::from),
                report.deck_flow2.map_or(-1, i32::from),
                report.fingerprint,
            );
            if let Some(c) = &report.client {
                println!(
                    "client: sent={} answered={} done={} first_request_ms={:?} last_answer_ms={:?} log_toc={:?} \
                     param_toc={:?} stalled_on={:?} nrf_radio_raw_down={} usart6_rx_kept_for_dma={} \
                     usart6_rx_stolen_from_dma={}",
                    c.sent,
                    c.answered,
                    c.done,
                    c.first_request_ms,
                    c.last_answer_ms,
                    c.log_toc,
                    c.param_toc,
                    c.stalled_on,
                    report.nrf.radio_raw_down,
                    report.usart6_rx_kept_for_dma,
                    report.usart6_rx_stolen_from_dma
                );
            }
            for f in &report.faults_logged {
                println!("firmware fault: {f}");
            }
            if let Some(h) = &report.hover {
                println!(
                    "hover: passed={} took_off_at_s={:?} held_s={:.2} dev_xy_m={:.3} rms_xy_m={:.3} dev_z_m={:.3} landed_at_s={:?} \
                     landing_offset_m={:?} end_state={:?}",
                    h.passed,
                    h.took_off_at_s,
                    h.held_s,
                    h.hold_dev_xy_m,
                    h.hold_rms_xy_m,
                    h.hold_dev_z_m,
                    h.landed_at_s,
                    h.landing_offset_m,
                    h.mission_end_state
                );
            }
            if let Some(m) = &report.mission {
                println!(
                    "mission: outcome={} state={:?} mission_time_s={:?} collisions={} min_clearance_m={:?} distance_m={:.2} \
                     landings={:?}",
                    m.outcome,
                    m.mission_state,
                    m.mission_time_s,
                    m.collisions,
                    m.min_clearance_m,
                    m.distance_m,
                    m.landings
                );
            }
            if let Some(path) = &args.json {
                let text = match serde_json::to_string_pretty(&report) {
                    Ok(t) => t,
                    Err(e) => {
                        eprintln!("error: encoding the report: {e}");
                        return ExitCode::from(2);
                    }
                };
                if let Err(e) = std::fs::write(path, text) {
                    eprintln!("error: writing {}: {e}", path.display());
                    return ExitCode::from(2);
                }
            }
            if let (Some(path), Some(t)) = (&args.track, report.track.as_ref()) {
                let written = serde_json::to_string(t)
                    .map_err(|e| e.to_string())
                    .and_then(|text| std::fs::write(path, text).map_err(|e| e.to_string()));
                if let Err(e) = written {
                    eprintln!("error: writing {}: {e}", path.display());
                    return ExitCode::from(2);
                }
            }
            if let (Some(path), Some(m)) = (&args.sim_json, report.mission.as_ref()) {
                let world = report.world.as_deref().unwrap_or("default");
                let sim = SimReport::of(world, args.seed, m, report.virtual_s, report.wall_s);
                let written = serde_json::to_string_pretty(&sim)
                    .map_err(|e| e.to_string())
                    .and_then(|t| std::fs::write(path, t).map_err(|e| e.to_string()));
                if let Err(e) = written {
                    eprintln!("error: writing {}: {e}", path.display());
                    return ExitCode::from(2);
                }
            }
            match &args.check {
                Some(name) => match verdict::check(name, &report, passed) {
                    Ok(line) => {
                        println!("check {name}: {line}");
                        ExitCode::SUCCESS
                    }
                    Err(e) => {
                        eprintln!("check {name} failed: {e}");
                        ExitCode::from(1)
                    }
                },
                None if passed => ExitCode::SUCCESS,
                None => ExitCode::from(1),
            }
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod sim_report_tests {
    use super::*;

    #[test]
    fn the_sim_report_has_the_keys_of_interfaces_section_4() {
        let m = mission::MissionReport {
            outcome: "completed".into(),
            mission_state: Some(100),
            mission_time_s: Some(53.6),
            landings: vec![Landing {
                pad: 1,
                error_m: 0.02,
                on_pad: true,
            }],
            distance_m: 18.3,
            ..Default::default()
        };
        let v = serde_json::to_value(SimReport::of("default", 1, &m, 56.6, 1152.0)).unwrap();
        let keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
        // docs/formats.md (report format)'s one-run object, then the end state the image logged.
        for k in [
            "world",
            "seed",
            "outcome",
            "reason",
            "mission_time_s",
            "collisions",
            "min_clearance_m",
            "landings",
            "replans",
            "distance_m",
            "sim_time_s",
            "wall_time_s",
        ] {
            assert!(keys.contains(&k), "{k} missing from {keys:?}");
        }
        assert_eq!(v["outcome"], "completed");
        assert_eq!(v["landings"][0]["pad"], 1);
        assert_eq!(v["sim_time_s"], 56.6);
        assert!(v["reason"].is_null() && v["replans"].is_null());
    }
}
