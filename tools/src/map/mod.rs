//! `cfnav map`: download the map a drone (`radio://…`) or a simulator (`udp://…`, `cfnav sim --serve`) has
//! built — occupancy grid, current path, pad estimates — from its map memory (CRTP port 4, layout in
//! `cfnav::radio_binding::map_mem` and `docs/map-memory.md`), and draw it like the simulator's plot and/or write it as
//! JSON.
//!
//! The client is crazyflie-lib 0.8.2 (as `cfnav mission start`): it lists the drone's memories while
//! connecting; the map is the memory of a type it does not know (`UNKNOWN`) whose first bytes are the magic
//! `"CFNM"`, read through `RawMemory` (24-byte reads, pipelined). The header is read first, then the bytes
//! it says are used; the download is accepted when the CRC-32 of what was read matches the header's, and
//! read again (up to `--retries` times) when the map changed in between.
//!
//! Exit status: 0 downloaded (and drawn/written), 2 bad input, no connection, no map memory, or a map that
//! kept changing. Non-goals: writing the map, following it live. Units: metres, arena frame.

pub mod decode;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Args;
use crazyflie_lib::Crazyflie;
use crazyflie_lib::subsystems::memory::{MemoryType, RawMemory};

use crate::radio::connect::{ConnectError, connect_uri};
use crate::radio::toc_cache::DirTocCache;
use crate::sim::plot::{Labels, draw_labelled};
use crate::sim::runner::{RunReport, RunResult};
use cfnav_sim::world::World;
use decode::{DecodeError, HEADER_LEN, MapSnapshot, decode, header_total_len};

/// Exit status: bad input, no connection, no map.
pub const EXIT_ERROR: u8 = 2;

/// Arguments of `cfnav map`.
#[derive(Args, Debug)]
pub struct MapArgs {
    /// The drone: radio://N/CHANNEL/RATE/ADDRESS (Crazyradio), or a simulator: udp://127.0.0.1:19850.
    #[arg(long)]
    pub uri: String,
    /// Draw the map (.png or .svg), like `cfnav sim --plot`.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Write the decoded map as JSON (`-` for stdout).
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Also draw this world's true obstacles and pads under the map (a world file, as `cfnav sim --world`).
    #[arg(long, value_name = "FILE")]
    pub world: Option<PathBuf>,
    /// Downloads to try when the map changes during one.
    #[arg(long, default_value_t = 10)]
    pub retries: u32,
    /// Seconds to wait for the connection.
    #[arg(long, value_name = "S", default_value_t = 20.0)]
    pub connect_timeout: f64,
    /// Download the TOCs on every connection (no TOC cache).
    #[arg(long)]
    pub no_toc_cache: bool,
}

/// Runs `cfnav map`.
pub fn run_cli(args: &MapArgs) -> ExitCode {
    if args.plot.is_none() && args.json.is_none() {
        eprintln!("cfnav map: nothing to do: give --plot FILE and/or --json FILE");
        return ExitCode::from(EXIT_ERROR);
    }
    if !(args.connect_timeout.is_finite() && args.connect_timeout > 0.0) {
        eprintln!("cfnav map: --connect-timeout must be a positive number of seconds");
        return ExitCode::from(EXIT_ERROR);
    }
    let world = match &args.world {
        Some(p) => match World::load(p) {
            Ok(w) => Some(w),
            Err(e) => {
                eprintln!("cfnav map: {e}");
                return ExitCode::from(EXIT_ERROR);
            }
        },
        None => None,
    };
    let runtime = match tokio::runtime::Builder::new_multi_thread().enable_all().build() {
        Ok(r) => r,
        Err(e) => {
            eprintln!("cfnav map: cannot start the async runtime: {e}");
            return ExitCode::from(EXIT_ERROR);
        }
    };
    let snapshot = match runtime.block_on(connect_and_download(args)) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("cfnav map: {e}");
            return ExitCode::from(EXIT_ERROR);
        }
    };
    eprintln!("{}", summary(&snapshot));
    if let Some(path) = &args.json
        && let Err(e) = write_json(&snapshot, path)
    {
        eprintln!("cfnav map: {e}");
        return ExitCode::from(EXIT_ERROR);
    }
    if let Some(path) = &args.plot {
        if let Err(e) = plot(&snapshot, world.as_ref(), &args.uri, path) {
            eprintln!("cfnav map: {e}");
            return ExitCode::from(EXIT_ERROR);
        }
        eprintln!("plot written to {}", path.display());
    }
    ExitCode::SUCCESS
}

fn write_json(snapshot: &MapSnapshot, path: &Path) -> Result<(), String> {
    let text = serde_json::to_string_pretty(snapshot).map_err(|e| format!("cannot encode the map: {e}"))?;
    if path.as_os_str() == "-" {
        println!("{text}");
        Ok(())
    } else {
        std::fs::write(path, text + "\n").map_err(|e| format!("{}: {e}", path.display()))
    }
}

/// One line about the map.
pub fn summary(s: &MapSnapshot) -> String {
    let count = |code: u8| s.cells.iter().filter(|&&c| c == code).count();
    format!(
        "map {} × {} cells of {:.0} mm: {} occupied, {} inflated, {} free, {} unknown; path {} points; {} pad \
         records; mission.state {}; CRC {:#010x}",
        s.width,
        s.height,
        s.cell_size_m * 1000.0,
        count(3),
        count(2),
        count(1),
        count(0),
        s.path.len(),
        s.pads.len(),
        s.mission_state,
        s.crc32
    )
}

async fn connect(args: &MapArgs) -> Result<Crazyflie, String> {
    let uri = args.uri.as_str();
    let cache = if args.no_toc_cache {
        DirTocCache::disabled()
    } else {
        DirTocCache::default_dir().map_or_else(DirTocCache::disabled, DirTocCache::new)
    };
    if !["udp://", "radio://", "usb://"]
        .iter()
        .any(|scheme| uri.starts_with(scheme))
    {
        return Err(format!(
            "{uri}: not a link URI this tool knows: radio://N/CHANNEL/RATE/ADDRESS, usb://N or udp://HOST:PORT"
        ));
    }
    let timeout = Duration::from_secs_f64(args.connect_timeout);
    connect_uri(uri, timeout, cache).await.map_err(|e| match e {
        ConnectError::Open(text) => text,
        ConnectError::Link(e) => format!("{uri}: {e}"),
        ConnectError::TimedOut => format!(
            "{uri}: the connection did not complete within {:.0} s",
            args.connect_timeout
        ),
    })
}

async fn connect_and_download(args: &MapArgs) -> Result<MapSnapshot, String> {
    let began = Instant::now();
    let cf = connect(args).await?;
    eprintln!("connected to {} in {:.2} s", args.uri, began.elapsed().as_secs_f64());
    let result = download(&cf, args.retries.max(1)).await;
    let _ = tokio::time::timeout(Duration::from_secs(1), cf.disconnect()).await;
    result
}

/// Finds the map memory and downloads a consistent snapshot.
async fn download(cf: &Crazyflie, tries: u32) -> Result<MapSnapshot, String> {
    let devices: Vec<_> = cf
        .memory
        .get_memories(Some(MemoryType::UNKNOWN))
        .into_iter()
        .cloned()
        .collect();
    for device in devices {
        let Some(Ok(raw)) = cf.memory.open_memory::<RawMemory>(device.clone()).await else {
            continue;
        };
        let result = download_from(&raw, device.size as usize, tries).await;
        let _ = cf.memory.close_memory(raw).await;
        match result {
            Ok(s) => return Ok(s),
            Err(None) => continue,
            Err(Some(e)) => return Err(e),
        }
    }
    Err("the drone lists no cfnav map memory (is it running cfnav with the map memory?)".to_string())
}

/// `Err(None)`: not the map memory.
async fn download_from(raw: &RawMemory, size: usize, tries: u32) -> Result<MapSnapshot, Option<String>> {
    if size < HEADER_LEN {
        return Err(None);
    }
    let mut last = String::new();
    for attempt in 1..=tries {
        let header = raw
            .read(0, HEADER_LEN)
            .await
            .map_err(|e| Some(format!("reading the map header: {e}")))?;
        let total = match header_total_len(&header) {
            Ok(t) => t,
            Err(_) if attempt == 1 && header.get(..4) != Some(b"CFNM".as_slice()) => return Err(None),
            Err(e) => return Err(Some(e)),
        };
        if total > size {
            return Err(Some(format!("the map says {total} bytes, its memory has {size}")));
        }
        let mut bytes = header;
        if total > HEADER_LEN {
            let body = raw
                .read(HEADER_LEN, total - HEADER_LEN)
                .await
                .map_err(|e| Some(format!("reading the map: {e}")))?;
            bytes.extend_from_slice(&body);
        }
        match decode(&bytes) {
            Ok(s) => {
                if attempt > 1 {
                    eprintln!("the map changed during {} download(s); read again", attempt - 1);
                }
                return Ok(s);
            }
            Err(e @ DecodeError::ChangedWhileRead { .. }) => last = e.to_string(),
            Err(DecodeError::Bad(e)) => return Err(Some(e)),
        }
    }
    Err(Some(format!("{last}, {tries} times: giving up")))
}

/// The plot: the simulator's figure with the downloaded map as the believed map, the path as the last
/// planned path and the pad records as marks.
pub fn plot(s: &MapSnapshot, world: Option<&World>, uri: &str, path: &Path) -> Result<(), String> {
    let mut base = world.cloned().unwrap_or_else(World::default_world);
    if world.is_none() {
        base.name = "downloaded map".to_string();
        base.arena.size = [f32::from(s.width) * s.cell_size_m, f32::from(s.height) * s.cell_size_m];
        base.boxes.clear();
        base.cylinders.clear();
        base.pads.clear();
    }
    let n = usize::from(s.width) * usize::from(s.height);
    let believed = (
        s.width,
        s.height,
        (0..n).map(|i| s.cells.get(i).is_some_and(|&c| c >= 2)).collect(),
        (0..n).map(|i| s.cells.get(i) == Some(&3)).collect(),
    );
    let centre = |[x, y]: [u16; 2]| {
        (
            s.origin_m[0] + (f32::from(x) + 0.5) * s.cell_size_m,
            s.origin_m[1] + (f32::from(y) + 0.5) * s.cell_size_m,
        )
    };
    let result = RunResult {
        report: RunReport {
            mission_state: s.mission_state,
            // The downloaded map does not say which mission drew it.
            ..RunReport::without_flight(base.name.clone(), "downloaded", "unknown")
        },
        trace: Vec::new(),
        paths: if s.path.is_empty() {
            Vec::new()
        } else {
            vec![s.path.iter().copied().map(centre).collect()]
        },
        believed: Some(believed),
        pad_locks: s.pads.iter().filter(|p| p.locked).map(|p| (p.x_m, p.y_m)).collect(),
    };
    let count = |code: u8| s.cells.iter().filter(|&&c| c == code).count();
    let pads: Vec<String> = s
        .pads
        .iter()
        .map(|p| {
            format!(
                "{} ({:.2}, {:.2}) {:.2}{}",
                p.kind.replace('_', " "),
                p.x_m,
                p.y_m,
                p.confidence,
                if p.locked { " locked" } else { "" }
            )
        })
        .collect();
    let labels = Labels {
        title: format!("cfnav map from {uri}: mission.state {}", s.mission_state),
        subtitle: [
            format!(
                "{} x {} cells: {} occupied, {} inflated, {} free, {} unknown; path {} points",
                s.width,
                s.height,
                count(3),
                count(2),
                count(1),
                count(0),
                s.path.len()
            ),
            if pads.is_empty() {
                "pads (confidence): none".to_string()
            } else {
                format!("pads (confidence): {}", pads.join("; "))
            },
        ],
        world_known: world.is_some(),
    };
    draw_labelled(&base, &result, path, Some(&labels))
}
