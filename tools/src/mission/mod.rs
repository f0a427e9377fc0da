//! `cfnav mission start`: connect to a drone (`radio://…`, through a Crazyradio) or a simulator
//! (`udp://127.0.0.1:19850`, `cfnav sim --serve`), set the mission parameters, write `mission.start = 1` and
//! show the mission's state, position and battery until it ends (docs/formats.md (commands), docs/radio.md).
//!
//! The client is crazyflie-lib 0.8.2 (with crazyflie-link 0.5.1, used through crazyflie-lib's re-export so
//! there is one copy): its parameter writes by name, a log block of `mission.state`, `stateEstimate.x/y/z`,
//! `pm.vbat`, the console and link pings. `udp://` goes through [`udp_link::UdpLink`] (crazyflie-link has
//! no UDP link); anything else goes to crazyflie-link's `LinkContext` (`radio://`, `usb://`).
//!
//! Exit status: 0 the mission completed (`mission.state` 100); 1 it ended without completing (≥ 101, the
//! value naming why) or `--timeout` passed (the mission is then aborted); 2 bad input, no connection, a
//! missing parameter or log variable, a refused parameter write, or the link lost during the mission; 130
//! interrupted by Ctrl-C (after `mission.start = 0` was written if the mission had been started).
//!
//! A refused write (docs/radio.md) is seen as an echo that carries the value in effect instead of the
//! value written (crazyflie-lib then reports a parameter error); the firmware also says why on the console,
//! which is printed. A start the flight core refuses after the echo shows up as `mission.start` going back
//! to 0 (VALUE_UPDATED) before the mission was seen running.
//!
//! Non-goals: flying by setpoints, flashing, several drones at once. Units: metres, m/s, volts, seconds
//! (the times shown are the drone's clock, the log timestamps, from the first sample after the start).

pub mod progress;
#[cfg(test)]
mod sim_tests;

use std::collections::HashMap;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use clap::{Args, Subcommand};
use crazyflie_lib::crazyflie_link;
use crazyflie_lib::subsystems::log::{LogPeriod, LogStream};
use crazyflie_lib::{Crazyflie, Value};
use futures::StreamExt;
use tokio::sync::{mpsc, watch};

use crate::radio::connect::{ConnectError, connect_uri};
use crate::radio::toc_cache::DirTocCache;
use progress::{MissionTracker, Outcome, state_name};

/// Exit status: bad input, connection failure, refused write, link lost.
pub const EXIT_ERROR: u8 = 2;
/// Exit status after Ctrl-C (128 + SIGINT, as shells report it).
pub const EXIT_INTERRUPTED: u8 = 130;

/// How long a parameter write may wait for its echo.
const ECHO_TIMEOUT: Duration = Duration::from_secs(5);
/// How long the drone's console gets to explain a refusal before the command exits.
const CONSOLE_GRACE: Duration = Duration::from_millis(400);
/// Consecutive unanswered link pings (one a second) after which the link counts as lost.
const MAX_MISSED_PINGS: u32 = 4;
/// The log variables the command needs, and the optional battery voltage.
const LOG_STATE: &str = "mission.state";
const LOG_POSITION: [&str; 3] = ["stateEstimate.x", "stateEstimate.y", "stateEstimate.z"];
const LOG_VBAT: &str = "pm.vbat";
const PARAM_START: &str = "mission.start";
const PARAM_RESET_ESTIMATION: &str = "kalman.resetEstimation";

/// Arguments of `cfnav mission`.
#[derive(Args, Debug)]
pub struct MissionArgs {
    #[command(subcommand)]
    pub command: MissionCommand,
}

/// The `cfnav mission` subcommands.
#[derive(Subcommand, Debug)]
pub enum MissionCommand {
    /// Set the mission parameters, start the mission and show its progress until it ends (exit 0 completed,
    /// 1 ended without completing, 2 error or refused write, 130 Ctrl-C: the mission is aborted first).
    Start(StartArgs),
}

/// Arguments of `cfnav mission start`.
#[derive(Args, Debug)]
pub struct StartArgs {
    /// The drone: radio://N/CHANNEL/RATE/ADDRESS (Crazyradio), or a simulator: udp://127.0.0.1:19850.
    #[arg(long)]
    pub uri: String,
    /// Nominal goal, arena frame, m (mission.goalX/goalY); without it the drone's value stays.
    #[arg(long, value_name = "X,Y", value_parser = parse_xy, allow_hyphen_values = true)]
    pub goal: Option<(f32, f32)>,
    /// Where the drone stands, arena frame, m (mission.startX/startY, then kalman.resetEstimation = 1: the
    /// estimate is re-anchored there).
    #[arg(long, value_name = "X,Y", value_parser = parse_xy, allow_hyphen_values = true)]
    pub start: Option<(f32, f32)>,
    /// The room: arena size along x and y, m (mission.arenaX/arenaY), written before the positions (which
    /// the drone checks against the arena in effect).
    #[arg(long, value_name = "X,Y", value_parser = parse_xy, allow_hyphen_values = true)]
    pub arena: Option<(f32, f32)>,
    /// Which sides of the arena are walls (mission.walls): a bitmask, south (y = 0) 1, east 2, north 4,
    /// west (x = 0) 8; 15 a walled box, 0 an open floor.
    #[arg(long, value_name = "MASK", value_parser = clap::value_parser!(u8).range(0..=15))]
    pub walls: Option<u8>,
    /// Cruise height, m (mission.height).
    #[arg(long, value_name = "M", value_parser = parse_finite, allow_hyphen_values = true)]
    pub height: Option<f32>,
    /// Cruise speed, m/s (mission.speed).
    #[arg(long, value_name = "M/S", value_parser = parse_finite, allow_hyphen_values = true)]
    pub speed: Option<f32>,
    /// Seconds to wait for the connection (link, protocol version, TOCs).
    #[arg(long, value_name = "S", default_value_t = 20.0, value_parser = parse_positive)]
    pub connect_timeout: f64,
    /// Give up after this many wall seconds: abort the mission and exit 1.
    #[arg(long, value_name = "S", value_parser = parse_positive)]
    pub timeout: Option<f64>,
    /// Log period of the state, position and battery, ms (10..=2550).
    #[arg(long, value_name = "MS", default_value_t = 100, value_parser = clap::value_parser!(u64).range(10..=2550))]
    pub log_period_ms: u64,
    /// When the output is not a terminal: print a progress line every this many wall seconds (state
    /// changes are always printed at once).
    #[arg(long, value_name = "S", default_value_t = 1.0, value_parser = parse_positive)]
    pub print_every: f64,
    /// After Ctrl-C: follow the landing for at most this many wall seconds before exiting.
    #[arg(long, value_name = "S", default_value_t = 5.0, value_parser = parse_non_negative)]
    pub abort_follow: f64,
    /// Folder of the TOC cache (default: $XDG_CACHE_HOME/cfnav/toc or ~/.cache/cfnav/toc).
    #[arg(long, value_name = "DIR")]
    pub toc_cache: Option<PathBuf>,
    /// Download the TOCs on every connection.
    #[arg(long, conflicts_with = "toc_cache")]
    pub no_toc_cache: bool,
}

fn parse_finite(s: &str) -> Result<f32, String> {
    let v: f32 = s.trim().parse().map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("'{s}' is not a finite number"))
    }
}

fn parse_positive(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a positive number of seconds")),
    }
}

fn parse_non_negative(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(format!("'{s}' is not a number of seconds ≥ 0")),
    }
}

/// `X,Y` in metres.
pub fn parse_xy(s: &str) -> Result<(f32, f32), String> {
    let mut parts = s.split(',');
    match (parts.next(), parts.next(), parts.next()) {
        (Some(x), Some(y), None) => Ok((parse_finite(x)?, parse_finite(y)?)),
        _ => Err(format!("'{s}' is not X,Y (two numbers in metres, e.g. 5.0,1.5)")),
    }
}

/// The parameter writes `args` asks for, in the order they are written: the room first (the side that
/// shrinks before the other, so that each write holds no more cells than the arena in effect or the one
/// asked for: the drone checks a side against the other side in effect; `arena_y_now` is the drone's
/// `mission.arenaY`), then the start, height, speed, and the goal last (so a refused start position is
/// reported before it). Every value is a float but `mission.walls` ([`wire_value`]).
pub fn requested_writes(args: &StartArgs, arena_y_now: Option<f32>) -> Vec<(&'static str, f32)> {
    let mut w = Vec::new();
    if let Some((x, y)) = args.arena {
        if arena_y_now.is_some_and(|now| y < now) {
            w.push(("mission.arenaY", y));
            w.push(("mission.arenaX", x));
        } else {
            w.push(("mission.arenaX", x));
            w.push(("mission.arenaY", y));
        }
    }
    if let Some(m) = args.walls {
        w.push(("mission.walls", f32::from(m)));
    }
    if let Some((x, y)) = args.start {
        w.push(("mission.startX", x));
        w.push(("mission.startY", y));
    }
    if let Some(h) = args.height {
        w.push(("mission.height", h));
    }
    if let Some(s) = args.speed {
        w.push(("mission.speed", s));
    }
    if let Some((x, y)) = args.goal {
        w.push(("mission.goalX", x));
        w.push(("mission.goalY", y));
    }
    w
}

/// The value written for `name`: `mission.walls` is a uint8 (the parser bounds it to 0..=15, exact in
/// an f32), every other mission parameter a float.
pub fn wire_value(name: &str, v: f32) -> Value {
    if name == "mission.walls" {
        Value::U8(v as u8)
    } else {
        Value::F32(v)
    }
}

/// Runs `cfnav mission …`.
pub fn run_cli(args: &MissionArgs) -> ExitCode {
    match &args.command {
        MissionCommand::Start(start) => ExitCode::from(run_start(start)),
    }
}

/// Runs `cfnav mission start` and returns its exit status.
pub fn run_start(args: &StartArgs) -> u8 {
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("error: cannot start the async runtime: {e}");
            return EXIT_ERROR;
        }
    };
    let code = runtime.block_on(start_mission(args));
    // Background tasks of the link may still wait on sockets or the radio: do not wait for them.
    runtime.shutdown_timeout(Duration::from_millis(200));
    code
}

/// Output: whole lines, plus (on a terminal) one live status line that the next line replaces.
#[derive(Clone)]
struct Printer {
    inner: Arc<Mutex<PrinterState>>,
}

struct PrinterState {
    tty: bool,
    status_shown: bool,
}

impl Printer {
    fn new() -> Self {
        Self {
            inner: Arc::new(Mutex::new(PrinterState {
                tty: std::io::stdout().is_terminal(),
                status_shown: false,
            })),
        }
    }

    fn tty(&self) -> bool {
        self.inner.lock().unwrap_or_else(|p| p.into_inner()).tty
    }

    /// Writes `text` to stdout; a closed stdout (`| head`) is not an error worth stopping a mission for.
    fn emit(text: &str) {
        #[cfg(test)]
        print!("{text}");
        #[cfg(not(test))]
        {
            use std::io::Write as _;
            let mut out = std::io::stdout().lock();
            let _ = out.write_all(text.as_bytes());
            let _ = out.flush();
        }
    }

    fn line(&self, text: &str) {
        let mut st = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        let clear = if st.status_shown { "\r\x1b[K" } else { "" };
        st.status_shown = false;
        Self::emit(&format!("{clear}{text}\n"));
    }

    /// The live line: rewritten in place on a terminal, a plain line otherwise.
    fn status(&self, text: &str) {
        let mut st = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        if st.tty {
            Self::emit(&format!("\r\x1b[K{text}"));
            st.status_shown = true;
        } else {
            Self::emit(&format!("{text}\n"));
        }
    }

    fn error(&self, text: &str) {
        let mut st = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        if st.status_shown {
            Self::emit("\n");
            st.status_shown = false;
        }
        eprintln!("error: {text}");
    }
}

/// One decoded log sample.
#[derive(Clone, Copy, Debug)]
struct Sample {
    timestamp_ms: u32,
    state: u8,
    position_m: [f64; 3],
    vbat_v: Option<f64>,
}

impl Sample {
    fn decode(timestamp_ms: u32, data: &HashMap<String, Value>) -> Option<Self> {
        let num = |name: &str| data.get(name).map(Value::to_f64_lossy);
        let state = num(LOG_STATE)?;
        Some(Self {
            timestamp_ms,
            state: state.clamp(0.0, 255.0) as u8,
            position_m: [num(LOG_POSITION[0])?, num(LOG_POSITION[1])?, num(LOG_POSITION[2])?],
            vbat_v: num(LOG_VBAT),
        })
    }

    fn describe(&self, mission_time_ms: u32) -> String {
        let [x, y, z] = self.position_m;
        let vbat = self.vbat_v.map_or(String::new(), |v| format!("  vbat {v:.2} V"));
        format!(
            "[{:7.1} s] state {:3} {:<38} pos ({x:5.2}, {y:5.2}, {z:4.2}) m{vbat}",
            f64::from(mission_time_ms) * 1e-3,
            self.state,
            state_name(self.state),
        )
    }
}

/// Why the command stops early.
struct Failure(String);

impl<E: std::fmt::Display> From<E> for Failure {
    fn from(e: E) -> Self {
        Failure(e.to_string())
    }
}

/// Ctrl-C presses, counted.
fn watch_ctrl_c() -> watch::Receiver<u32> {
    let (tx, rx) = watch::channel(0u32);
    tokio::spawn(async move {
        let mut presses = 0u32;
        while tokio::signal::ctrl_c().await.is_ok() {
            presses += 1;
            if tx.send(presses).is_err() {
                break;
            }
        }
    });
    rx
}

async fn interrupted(rx: &mut watch::Receiver<u32>) {
    if rx.changed().await.is_err() {
        // The signal listener is gone: never fire.
        std::future::pending::<()>().await;
    }
}

/// Everything set up before the start: the connection, the log stream, the current parameter values.
struct Session {
    cf: Arc<Crazyflie>,
    stream: LogStream,
    has_vbat: bool,
}

async fn start_mission(args: &StartArgs) -> u8 {
    let printer = Printer::new();
    let mut sigint = watch_ctrl_c();
    let setup = tokio::select! {
        r = connect_and_prepare(args, &printer) => r,
        _ = interrupted(&mut sigint) => {
            printer.line("interrupted before the mission started: mission.start was not written");
            return EXIT_INTERRUPTED;
        }
    };
    let session = match setup {
        Ok(s) => s,
        Err(Failure(msg)) => {
            printer.error(&msg);
            return EXIT_ERROR;
        }
    };
    let code = fly(args, &printer, &session, &mut sigint).await;
    let Session { cf, stream, .. } = session;
    drop(stream);
    let _ = tokio::time::timeout(Duration::from_secs(1), cf.disconnect()).await;
    code
}

fn link_error_text(uri: &str, e: &crazyflie_lib::Error) -> String {
    use crazyflie_link::Error as L;
    match e {
        crazyflie_lib::Error::LinkError(L::InvalidUri | L::InvalidUriScheme) => format!(
            "{uri}: not a link URI this tool knows: radio://N/CHANNEL/RATE/ADDRESS (e.g. \
             radio://0/80/2M/E7E7E7E7E7, all four parts), usb://N or udp://HOST:PORT"
        ),
        crazyflie_lib::Error::LinkError(L::CrazyradioError(crazyflie_link::crazyradio::Error::NotFound)) => {
            format!("{uri}: no Crazyradio found (plugged in? may this user open it? see the udev rules)")
        }
        crazyflie_lib::Error::ProtocolVersionNotSupported { found, .. } => {
            format!("{uri}: the drone speaks CRTP protocol version {found}; crazyflie-lib needs 12 or 13")
        }
        other => format!("{uri}: {other}"),
    }
}

async fn connect(args: &StartArgs, printer: &Printer) -> Result<Arc<Crazyflie>, Failure> {
    let uri = args.uri.as_str();
    let cache = if args.no_toc_cache {
        DirTocCache::disabled()
    } else {
        match args.toc_cache.clone().or_else(DirTocCache::default_dir) {
            Some(dir) => DirTocCache::new(dir),
            None => DirTocCache::disabled(),
        }
    };
    if !["udp://", "radio://", "usb://"]
        .iter()
        .any(|scheme| uri.starts_with(scheme))
    {
        return Err(Failure(format!(
            "{uri}: not a link URI this tool knows: radio://N/CHANNEL/RATE/ADDRESS, usb://N or udp://HOST:PORT"
        )));
    }
    if let Some(rest) = uri.strip_prefix("radio://") {
        // crazyflie-link 0.5.1 needs all four parts (its docs call the address optional, its parser does not).
        if rest.trim_end_matches('/').split(['/', '?']).take(4).count() != 4 {
            return Err(Failure(format!(
                "{uri}: expected radio://N/CHANNEL/RATE/ADDRESS, e.g. radio://0/80/2M/E7E7E7E7E7"
            )));
        }
    }
    let timeout = Duration::from_secs_f64(args.connect_timeout);
    let began = Instant::now();
    printer.line(&format!("connecting to {uri} ..."));
    let cf = connect_uri(uri, timeout, cache).await.map_err(|e| {
        Failure(match e {
            ConnectError::Open(text) => text,
            ConnectError::Link(e) => link_error_text(uri, &e),
            ConnectError::TimedOut => format!(
                "{uri}: the connection did not complete within {:.0} s (drone off, wrong channel or address, \
                 or no CRTP firmware answering?)",
                args.connect_timeout
            ),
        })
    })?;
    printer.line(&format!(
        "connected in {:.2} s: {} parameters, {} log variables",
        began.elapsed().as_secs_f64(),
        cf.param.names().len(),
        cf.log.names().len()
    ));
    Ok(Arc::new(cf))
}

async fn connect_and_prepare(args: &StartArgs, printer: &Printer) -> Result<Session, Failure> {
    let uri = args.uri.as_str();
    let cf = connect(args, printer).await?;

    // What the drone must offer.
    let params = cf.param.names();
    let logs = cf.log.names();
    let arena_y_now = if args.arena.is_some() && params.iter().any(|p| p == "mission.arenaY") {
        let v: Value = with_timeout("mission.arenaY", cf.param.get("mission.arenaY")).await?;
        Some(v.to_f64_lossy() as f32)
    } else {
        None
    };
    let writes = requested_writes(args, arena_y_now);
    for name in std::iter::once(PARAM_START).chain(writes.iter().map(|(n, _)| *n)) {
        if !params.iter().any(|p| p == name) {
            return Err(Failure(format!(
                "{uri}: the drone has no parameter {name} (is it running cfnav?)"
            )));
        }
    }
    for name in std::iter::once(LOG_STATE).chain(LOG_POSITION) {
        if !logs.iter().any(|l| l == name) {
            return Err(Failure(format!("{uri}: the drone has no log variable {name}")));
        }
    }
    let has_vbat = logs.iter().any(|l| l == LOG_VBAT);

    // The drone's console, printed as it comes (a refused write is explained there).
    let mut console = cf.console.line_stream_no_history().await;
    let console_printer = printer.clone();
    tokio::spawn(async move {
        while let Some(line) = console.next().await {
            console_printer.line(&format!("  [drone console] {}", line.trim_end()));
        }
    });

    // The values in effect (read once: a refused write leaves them so).
    let mut current = HashMap::new();
    for name in [
        "mission.arenaX",
        "mission.arenaY",
        "mission.walls",
        "mission.startX",
        "mission.startY",
        "mission.goalX",
        "mission.goalY",
        "mission.height",
        "mission.speed",
    ] {
        if params.iter().any(|p| p == name) {
            let v: Value = with_timeout(name, cf.param.get(name)).await?;
            current.insert(name, v.to_f64_lossy());
        }
    }
    let show = |n: &str| current.get(n).map_or("?".to_string(), |v| format!("{v:.2}"));
    printer.line(&format!(
        "on the drone: arena {} × {} m (walls {})  start ({}, {})  goal ({}, {})  height {} m  speed {} m/s",
        show("mission.arenaX"),
        show("mission.arenaY"),
        current
            .get("mission.walls")
            .map_or("?".to_string(), |v| format!("{v:.0}")),
        show("mission.startX"),
        show("mission.startY"),
        show("mission.goalX"),
        show("mission.goalY"),
        show("mission.height"),
        show("mission.speed"),
    ));

    for (name, value) in writes {
        match tokio::time::timeout(ECHO_TIMEOUT, cf.param.set(name, wire_value(name, value))).await {
            Ok(Ok(())) => printer.line(&format!("set {name} = {value:.3}: accepted (echo {value:.3})")),
            Ok(Err(crazyflie_lib::Error::ParamError(msg))) if msg.starts_with("Error setting parameter") => {
                // crazyflie-lib saw an echo that is not the value written: the firmware refused it and
                // echoed the value in effect (docs/radio.md).
                let kept = current
                    .get(name)
                    .map_or("its previous value".to_string(), |v| format!("{v:.3}"));
                tokio::time::sleep(CONSOLE_GRACE).await;
                return Err(Failure(format!(
                    "the drone refused {name} = {value:.3}: its echo carried the value in effect ({kept})"
                )));
            }
            Ok(Err(e)) => return Err(Failure(format!("writing {name} = {value}: {e}"))),
            Err(_) => {
                return Err(Failure(format!(
                    "no echo for {name} = {value} within {} s",
                    ECHO_TIMEOUT.as_secs()
                )));
            }
        }
    }

    // `--start` says where the drone stands: re-anchor the estimate there (docs/mission-start.md), or a
    // round trip is refused once the estimate is elsewhere.
    if args.start.is_some() && params.iter().any(|p| p == PARAM_RESET_ESTIMATION) {
        match tokio::time::timeout(ECHO_TIMEOUT, cf.param.set(PARAM_RESET_ESTIMATION, Value::U8(1))).await {
            Ok(Ok(())) => printer.line("set kalman.resetEstimation = 1: the estimate re-anchored at the start"),
            Ok(Err(e)) => return Err(Failure(format!("writing {PARAM_RESET_ESTIMATION} = 1: {e}"))),
            Err(_) => {
                return Err(Failure(format!(
                    "no echo for {PARAM_RESET_ESTIMATION} = 1 within {} s",
                    ECHO_TIMEOUT.as_secs()
                )));
            }
        }
    }

    // The log block: state, position, battery.
    let mut block = with_timeout("creating the log block", cf.log.create_block()).await?;
    for name in std::iter::once(LOG_STATE)
        .chain(LOG_POSITION)
        .chain(has_vbat.then_some(LOG_VBAT))
    {
        with_timeout(name, block.add_variable(name)).await?;
    }
    let period = LogPeriod::from_millis(args.log_period_ms)?;
    let stream = with_timeout("starting the log block", block.start(period)).await?;
    Ok(Session { cf, stream, has_vbat })
}

async fn with_timeout<T>(
    what: &str,
    f: impl std::future::Future<Output = crazyflie_lib::Result<T>>,
) -> Result<T, Failure> {
    match tokio::time::timeout(ECHO_TIMEOUT, f).await {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(Failure(format!("{what}: {e}"))),
        Err(_) => Err(Failure(format!(
            "{what}: no answer within {} s",
            ECHO_TIMEOUT.as_secs()
        ))),
    }
}

/// Pings the drone once a second and reports whether each ping was answered.
fn spawn_pinger(cf: Arc<Crazyflie>) -> (mpsc::Receiver<bool>, tokio::task::JoinHandle<()>) {
    let (tx, rx) = mpsc::channel(4);
    let handle = tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tick.tick().await;
            let ok = cf.link_service.ping().await.is_ok();
            if tx.send(ok).await.is_err() {
                break;
            }
        }
    });
    (rx, handle)
}

/// What ended the monitoring loop.
enum Ending {
    Outcome(Outcome),
    Interrupted,
    TimedOut,
    Failed(String),
}

async fn next_sample(stream: &LogStream) -> Result<Sample, String> {
    loop {
        let data = stream.next().await.map_err(|e| format!("the link was lost: {e}"))?;
        if let Some(s) = Sample::decode(data.timestamp, &data.data) {
            return Ok(s);
        }
    }
}

async fn fly(args: &StartArgs, printer: &Printer, session: &Session, sigint: &mut watch::Receiver<u32>) -> u8 {
    let cf = &session.cf;
    let stream = &session.stream;
    let mut tracker = MissionTracker::new();
    if !session.has_vbat {
        printer.line("(the drone has no pm.vbat log variable: no battery shown)");
    }

    // The state before the start (a drone that flew before still shows its last final code).
    let first = tokio::select! {
        r = tokio::time::timeout(Duration::from_secs(3), next_sample(stream)) => r,
        _ = interrupted(sigint) => {
            printer.line("interrupted before the mission started: mission.start was not written");
            return EXIT_INTERRUPTED;
        }
    };
    match first {
        Ok(Ok(s)) => {
            tracker.on_sample(s.state, s.timestamp_ms);
            printer.line(&format!("before the start: {}", s.describe(0)));
        }
        Ok(Err(e)) => {
            printer.error(&e);
            return EXIT_ERROR;
        }
        Err(_) => {
            printer.error("no log data within 3 s of starting the log block");
            return EXIT_ERROR;
        }
    }

    let mut changes = match cf.param.watch_change().await {
        Ok(c) => c,
        Err(e) => {
            printer.error(&format!("watching parameters: {e}"));
            return EXIT_ERROR;
        }
    };

    let began = Instant::now();
    match tokio::time::timeout(ECHO_TIMEOUT, cf.param.set(PARAM_START, 1u8)).await {
        Ok(Ok(())) => {
            tracker.start_accepted();
            printer.line("mission.start = 1: accepted, the mission runs (Ctrl-C aborts it)");
        }
        Ok(Err(crazyflie_lib::Error::ParamError(msg))) if msg.starts_with("Error setting parameter") => {
            tokio::time::sleep(CONSOLE_GRACE).await;
            printer.error("the drone refused mission.start = 1: its echo carried the value in effect (0)");
            return EXIT_ERROR;
        }
        Ok(Err(e)) => {
            printer.error(&format!("writing mission.start = 1: {e}"));
            return EXIT_ERROR;
        }
        Err(_) => {
            // The write may have arrived: make sure nothing flies unseen.
            let _ = tokio::time::timeout(Duration::from_secs(2), cf.param.set(PARAM_START, 0u8)).await;
            printer.error(&format!(
                "no echo for mission.start = 1 within {} s (mission.start = 0 sent to be safe)",
                ECHO_TIMEOUT.as_secs()
            ));
            return EXIT_ERROR;
        }
    }

    let (mut pings, pinger) = spawn_pinger(cf.clone());
    let deadline = args
        .timeout
        .map(|s| tokio::time::Instant::now() + Duration::from_secs_f64(s));
    let tty = printer.tty();
    let status_every = if tty {
        Duration::from_millis(100)
    } else {
        Duration::from_secs_f64(args.print_every)
    };
    let mut status_tick = tokio::time::interval(status_every);
    status_tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut last_sample: Option<Sample> = None;
    let mut last_sample_at = Instant::now();
    let mut last_state: Option<u8> = None;
    let mut missed_pings = 0u32;
    // mission.start went back to 0 before the mission was seen running: refused by the flight core, unless a
    // final code arrives shortly (a mission that ended between two samples).
    let mut start_reset_at: Option<tokio::time::Instant> = None;

    let ending = loop {
        let refusal_check = async {
            match start_reset_at {
                Some(t) => tokio::time::sleep_until(t + Duration::from_millis(1500)).await,
                None => std::future::pending().await,
            }
        };
        let give_up = async {
            match deadline {
                Some(t) => tokio::time::sleep_until(t).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            sample = next_sample(stream) => match sample {
                Ok(s) => {
                    let outcome = tracker.on_sample(s.state, s.timestamp_ms);
                    if last_state != Some(s.state) {
                        printer.line(&format!("* {}", s.describe(tracker.mission_time_ms(s.timestamp_ms))));
                        last_state = Some(s.state);
                    }
                    last_sample = Some(s);
                    last_sample_at = Instant::now();
                    if let Some(o) = outcome {
                        break Ending::Outcome(o);
                    }
                }
                Err(e) => break Ending::Failed(e),
            },
            change = changes.next() => {
                if let Some((name, value)) = change
                    && name == PARAM_START
                    && value.to_f64_lossy() == 0.0
                    && !tracker.seen_running()
                    && start_reset_at.is_none()
                {
                    start_reset_at = Some(tokio::time::Instant::now());
                }
            }
            _ = refusal_check => {
                break Ending::Failed(
                    "the drone refused the start: mission.start went back to 0 before the mission ran".into(),
                );
            }
            ping = pings.recv() => {
                match ping {
                    Some(true) => missed_pings = 0,
                    Some(false) => {
                        missed_pings += 1;
                        if missed_pings >= MAX_MISSED_PINGS {
                            break Ending::Failed(format!(
                                "the link was lost: {missed_pings} pings in a row unanswered"
                            ));
                        }
                    }
                    None => {}
                }
            }
            _ = status_tick.tick() => {
                let silent_s = last_sample_at.elapsed().as_secs_f64();
                if silent_s >= 1.0 {
                    printer.status(&format!("  (no log data from the drone for {silent_s:.0} s)"));
                } else if let Some(s) = last_sample {
                    printer.status(&format!("  {}", s.describe(tracker.mission_time_ms(s.timestamp_ms))));
                }
            }
            _ = interrupted(sigint) => break Ending::Interrupted,
            _ = give_up => break Ending::TimedOut,
        }
    };
    pinger.abort();

    match ending {
        Ending::Outcome(outcome) => {
            let t = last_sample.map_or(0, |s| tracker.mission_time_ms(s.timestamp_ms));
            printer.line(&format!(
                "mission ended after {:.1} s (drone clock), {:.1} s wall: final state {} ({})",
                f64::from(t) * 1e-3,
                began.elapsed().as_secs_f64(),
                outcome.code(),
                state_name(outcome.code())
            ));
            outcome.exit_code()
        }
        Ending::Failed(msg) => {
            tokio::time::sleep(CONSOLE_GRACE).await;
            // A closed link knows why (e.g. the simulator is gone); a live one does not answer here.
            match tokio::time::timeout(Duration::from_millis(300), cf.wait_disconnect()).await {
                Ok(reason) if msg.starts_with("the link was lost") => {
                    printer.error(&format!("the link was lost: {reason}"))
                }
                _ => printer.error(&msg),
            }
            EXIT_ERROR
        }
        Ending::Interrupted => {
            printer.line("Ctrl-C: aborting the mission (writing mission.start = 0)");
            abort(args, printer, session, &mut tracker, sigint).await;
            printer.line(&format!("exit {EXIT_INTERRUPTED} (interrupted)"));
            EXIT_INTERRUPTED
        }
        Ending::TimedOut => {
            printer.line(&format!(
                "no end within --timeout {} s: aborting the mission (writing mission.start = 0)",
                args.timeout.unwrap_or_default()
            ));
            abort(args, printer, session, &mut tracker, sigint).await;
            1
        }
    }
}

/// Writes `mission.start = 0`, waits for its echo, then shows the landing for at most `--abort-follow`
/// seconds (a second Ctrl-C stops waiting).
async fn abort(
    args: &StartArgs,
    printer: &Printer,
    session: &Session,
    tracker: &mut MissionTracker,
    sigint: &mut watch::Receiver<u32>,
) {
    match tokio::time::timeout(Duration::from_secs(2), session.cf.param.set(PARAM_START, 0u8)).await {
        Ok(Ok(())) => printer.line("mission.start = 0: accepted (echo 0), the drone lands where it is"),
        Ok(Err(e)) => printer.error(&format!("writing mission.start = 0: {e}")),
        Err(_) => printer.error("no echo for mission.start = 0 within 2 s: the abort may not have arrived"),
    }
    if args.abort_follow <= 0.0 {
        return;
    }
    let follow_until = tokio::time::Instant::now() + Duration::from_secs_f64(args.abort_follow);
    let mut last_state = tracker.last_code();
    loop {
        tokio::select! {
            sample = next_sample(&session.stream) => match sample {
                Ok(s) => {
                    let ended = tracker.on_sample(s.state, s.timestamp_ms).is_some() || s.state >= 100;
                    if last_state != Some(s.state) {
                        printer.line(&format!("* {}", s.describe(tracker.mission_time_ms(s.timestamp_ms))));
                        last_state = Some(s.state);
                    }
                    if ended {
                        printer.line(&format!("final state {} ({})", s.state, state_name(s.state)));
                        return;
                    }
                }
                Err(e) => {
                    printer.error(&e);
                    return;
                }
            },
            _ = tokio::time::sleep_until(follow_until) => {
                printer.line(&format!(
                    "stopped following after {} s; the drone goes on landing",
                    args.abort_follow
                ));
                return;
            }
            _ = interrupted(sigint) => {
                printer.line("second Ctrl-C: not waiting for the landing");
                return;
            }
        }
    }
}

/// `cfnav <args…>` parsed as a `mission start` command line (the tests' command-line parser).
#[cfg(test)]
fn parse_start(args: &[&str]) -> Result<StartArgs, clap::Error> {
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(subcommand)]
        command: Top,
    }

    #[derive(clap::Subcommand)]
    enum Top {
        Mission(MissionArgs),
    }

    let cli = Cli::try_parse_from(std::iter::once("cfnav").chain(args.iter().copied()))?;
    let Top::Mission(MissionArgs {
        command: MissionCommand::Start(start),
    }) = cli.command;
    Ok(start)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_parse() {
        let a = parse_start(&[
            "mission",
            "start",
            "--uri",
            "udp://127.0.0.1:19851",
            "--goal",
            "5.0,1.5",
            "--start",
            "0.6, 1.3",
            "--height",
            "0.5",
            "--speed",
            "0.4",
        ])
        .unwrap();
        assert_eq!(a.goal, Some((5.0, 1.5)));
        assert_eq!(a.start, Some((0.6, 1.3)));
        assert_eq!(
            requested_writes(&a, None),
            vec![
                ("mission.startX", 0.6),
                ("mission.startY", 1.3),
                ("mission.height", 0.5),
                ("mission.speed", 0.4),
                ("mission.goalX", 5.0),
                ("mission.goalY", 1.5),
            ]
        );
        // Negative numbers are values (the drone refuses them, not the parser).
        let a = parse_start(&["mission", "start", "--uri", "u", "--goal", "-1,2"]).unwrap();
        assert_eq!(a.goal, Some((-1.0, 2.0)));
        assert!(requested_writes(&parse_start(&["mission", "start", "--uri", "u"]).unwrap(), None).is_empty());
    }

    #[test]
    fn the_room_is_written_first_the_shrinking_side_before_the_other() {
        let a = parse_start(&[
            "mission", "start", "--uri", "u", "--arena", "8,2", "--walls", "5", "--goal", "7,1",
        ])
        .unwrap();
        assert_eq!(a.arena, Some((8.0, 2.0)));
        assert_eq!(a.walls, Some(5));
        // y shrinks from 3 to 2: it goes first, so 8 × 3 m is never asked of the drone.
        assert_eq!(
            requested_writes(&a, Some(3.0)),
            vec![
                ("mission.arenaY", 2.0),
                ("mission.arenaX", 8.0),
                ("mission.walls", 5.0),
                ("mission.goalX", 7.0),
                ("mission.goalY", 1.0),
            ]
        );
        // y grows: x first (x alone never holds more cells than the room asked for).
        let a = parse_start(&["mission", "start", "--uri", "u", "--arena", "4,4"]).unwrap();
        assert_eq!(
            requested_writes(&a, Some(3.0)),
            vec![("mission.arenaX", 4.0), ("mission.arenaY", 4.0)]
        );
        assert!(matches!(wire_value("mission.walls", 5.0), Value::U8(5)));
        assert!(matches!(wire_value("mission.arenaX", 5.0), Value::F32(v) if v == 5.0));
        for bad in ["16", "-1", "x"] {
            assert!(
                parse_start(&["mission", "start", "--uri", "u", "--walls", bad]).is_err(),
                "{bad}"
            );
        }
        assert!(parse_start(&["mission", "start", "--uri", "u", "--arena", "8"]).is_err());
    }

    #[test]
    fn bad_options_are_refused() {
        for bad in [
            &["mission", "start"][..],
            &["mission", "start", "--uri", "u", "--goal", "5"],
            &["mission", "start", "--uri", "u", "--goal", "5,1,2"],
            &["mission", "start", "--uri", "u", "--goal", "x,1"],
            &["mission", "start", "--uri", "u", "--goal", "nan,1"],
            &["mission", "start", "--uri", "u", "--height", "inf"],
            &["mission", "start", "--uri", "u", "--log-period-ms", "5"],
            &["mission", "start", "--uri", "u", "--timeout", "0"],
            &["mission", "start", "--uri", "u", "--toc-cache", "d", "--no-toc-cache"],
        ] {
            assert!(parse_start(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn unknown_or_incomplete_uris_are_exit_2() {
        for uri in ["foo://x", "127.0.0.1:19850", "radio://0/80/2M", "udp://127.0.0.1"] {
            let a = parse_start(&["mission", "start", "--uri", uri, "--no-toc-cache"]).unwrap();
            assert_eq!(run_start(&a), EXIT_ERROR, "{uri}");
        }
    }

    #[test]
    fn samples_decode_by_name() {
        let mut data = HashMap::new();
        data.insert(LOG_STATE.to_string(), Value::U8(11));
        data.insert(LOG_POSITION[0].to_string(), Value::F32(1.5));
        data.insert(LOG_POSITION[1].to_string(), Value::F32(1.25));
        data.insert(LOG_POSITION[2].to_string(), Value::F32(0.5));
        let s = Sample::decode(1234, &data).unwrap();
        assert_eq!((s.state, s.position_m, s.vbat_v), (11, [1.5, 1.25, 0.5], None));
        let line = s.describe(2500);
        assert!(line.contains("state  11 navigating to the goal"), "{line}");
        assert!(line.contains("2.5 s"), "{line}");
        data.insert(LOG_VBAT.to_string(), Value::F32(3.9));
        assert!(Sample::decode(0, &data).unwrap().describe(0).contains("vbat 3.90 V"));
        data.remove(LOG_STATE);
        assert!(Sample::decode(0, &data).is_none());
    }
}
