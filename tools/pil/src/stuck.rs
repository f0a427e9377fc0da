//! `pil.stuck`: a slave that holds SDA low (the stuck bus a first flash can meet).
//!
//! Job: reproduce the bus a real chip leaves behind when a transfer is cut mid-byte (the MCU reset by the
//! watchdog or a debugger while the chip was sending a 0 bit): the slave keeps SDA low and waits for the
//! SCL clocks that finish its byte. Until then the STM32F4's I2C v1 cannot start anything: RM0090 §27.6.7
//! (SR2.BUSY) "set by hardware on detection of SDA or SCL low, cleared by hardware on detection of a Stop
//! condition ... still updated when the interface is disabled (PE=0)", and §27.6.1 (CR1.START) in slave
//! mode: "Start generation when the bus is free", so SB (§27.6.6) never comes. The slave lets go of SDA
//! after `k` falling SCL edges (`k` ≤ 9: the bits left of its byte and the acknowledge clock), or never (a
//! chip that is latched up or shorted).
//!
//! How the two halves of that are modelled, around rsemu 0.0.7's transactional I2C link (which moves no
//! wires):
//!
//! * **The controller's side** ([`StuckSlave`], an [`I2cSlave`] on the named bus): while SDA is held it
//!   reports [`I2cSlave::stretching`], which makes `st.i2c`'s transactional engine make no progress on any
//!   bus event, so a START set in CR1 stays pending and SB never comes, as on the part. BUSY is set by
//!   opening the fabric's transaction with a START to the reserved address 0x7F that nobody answers
//!   ([`StuckLine::hold_bus`]), and cleared (the STOP the recovery sends) on the first bus event after the
//!   release.
//! * **The pins' side** (the `pil.stuck` device): the SCL pad of the GPIO port drives a net with the
//!   board's pull-up, whose falling edges the slave counts (`scl`); the slave drives SDA's net, which has
//!   the pull-up too, so the port's IDR reads the line low while it holds (`sda`; rsemu's `st.gpio` reads
//!   IDR from a resolved net even in output mode, RM0090 §8.3.10). `scl-af`/`sda-af` are the I2C
//!   peripheral's own pad outputs, released: the transactional link drives no pins, and an open-drain pad
//!   in alternate-function mode must let go of the line rather than pull it low.
//!
//! Non-goals: no byte-level wired I2C (the chips on the bus stay transactional; a stuck slave that is one
//! of them is modelled as a separate holder of the line), no SDA edges seen by the slave (the recovery's
//! START/STOP after the clocks is not needed to release it), no re-sticking after a release.
//!
//! Units: SCL edges, ms of virtual time (set by the host). Sources: RM0090 §27 (I2C; §25 in rev. 4, as
//! rsemu cites it), §8.3.10 (GPIO open-drain input path); NXP UM10204 §3.1.16 (bus clear: nine clock
//! pulses while SDA is stuck low); the firmware's recovery, `cfnav::drivers::i2c_guard`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use rsemu::bus::i2c::{Ack, Address, Direction, I2cBus, I2cSlave};
use rsemu::core::device::{Device, DeviceClass, PropertySpec, RealizeCtx, ResetKind, SinkPin};
use rsemu::core::error::{Error, Result};
use rsemu::core::props::{Props, ValueKind};
use rsemu::core::wire::{Drive, Level, WireId, WireSink, WireSource};
use rsemu::machine::Instance;
use rsemu::machine::validate::{ClassSchema, PortDir, PropSchema};

/// The class name a machine file writes.
pub const CLASS_NAME: &str = "pil.stuck";

/// The reserved address (UM10204 Table 4: 1111 1XX is reserved) the model opens the fabric's transaction
/// with, so `st.i2c` reads BUSY; no model answers it.
const BUSY_ADDRESS: u8 = 0x7F;

/// When the slave lets go of SDA.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Release {
    /// After this many falling SCL edges (1..=9).
    AfterClocks(u32),
    /// Never (a latched-up chip).
    Never,
}

impl Release {
    /// `K` (1..=9) or `never`; `None` is the default, 9 (the most a byte and its acknowledge can need).
    pub fn parse(text: Option<&str>) -> std::result::Result<Self, String> {
        match text {
            None => Ok(Release::AfterClocks(9)),
            Some("never") => Ok(Release::Never),
            Some(k) => match k.parse::<u32>() {
                Ok(k @ 1..=9) => Ok(Release::AfterClocks(k)),
                _ => Err(format!("`{k}`: the clocks to release must be 1..=9 or `never`")),
            },
        }
    }
}

/// What the report prints.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct StuckStats {
    /// The fault as configured (`None`: not stuck).
    pub release: Option<Release>,
    /// Whether SDA is still held at the end.
    pub holding: bool,
    /// Falling SCL edges while SDA was held (the firmware's recovery clocks).
    pub clocks_seen: u32,
    /// Virtual ms at which SDA was let go (the host's slice in which it happened).
    pub released_at_ms: Option<u64>,
    /// Bus events the controller tried while SDA was held (half periods refused; a START that waits).
    pub stalled_half_periods: u64,
}

#[derive(Debug, Default)]
struct State {
    release: Option<Release>,
    clocks_seen: u32,
    released_at_ms: Option<u64>,
    scl_high: bool,
    sda: Option<WireSource>,
    stalled_half_periods: u64,
    /// The release happened: the next bus event clears BUSY first.
    free_bus: bool,
}

/// One stuck line (a bus's SDA): shared by the `pil.stuck` device, the [`StuckSlave`] and the host.
#[derive(Debug, Clone, Default)]
pub struct StuckLine {
    holding: Arc<AtomicBool>,
    state: Arc<Mutex<State>>,
    bus: Arc<OnceLock<Arc<I2cBus>>>,
}

impl StuckLine {
    /// A line held from power-on that lets go as `release` says; `None`: a healthy line.
    pub fn new(release: Option<Release>) -> Self {
        let line = Self::default();
        line.holding.store(release.is_some(), Ordering::Release);
        line.with(|s| {
            s.release = release;
            s.scl_high = true;
        });
        line
    }

    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        f(&mut self.state.lock().unwrap_or_else(|e| e.into_inner()))
    }

    /// Whether SDA is held low now.
    pub fn holding(&self) -> bool {
        self.holding.load(Ordering::Acquire)
    }

    /// Puts the slave on `bus` and, if SDA is held, opens the fabric's transaction so the controller reads
    /// BUSY (call before the machine runs).
    pub fn hold_bus(&self, bus: &Arc<I2cBus>) -> anyhow::Result<()> {
        let _ = self.bus.set(Arc::clone(bus));
        bus.attach(Arc::new(StuckSlave { line: self.clone() }))
            .map_err(|e| anyhow::anyhow!("attaching the stuck slave: {e}"))?;
        if self.holding() {
            let _ = bus.start(Address::Seven(BUSY_ADDRESS), Direction::Write);
        }
        Ok(())
    }

    /// The host's clock: records when the release happened (called once per slice).
    pub fn tick(&self, now_ms: u64) {
        if !self.holding() {
            self.with(|s| {
                if s.release.is_some() && s.released_at_ms.is_none() {
                    s.released_at_ms = Some(now_ms);
                }
            });
        }
    }

    pub fn stats(&self) -> StuckStats {
        let holding = self.holding();
        self.with(|s| StuckStats {
            release: s.release,
            holding,
            clocks_seen: s.clocks_seen,
            released_at_ms: s.released_at_ms,
            stalled_half_periods: s.stalled_half_periods,
        })
    }

    /// SCL moved to `high` (the resolved net).
    fn scl(&self, high: bool) {
        let released = self.with(|s| {
            let falling = s.scl_high && !high;
            s.scl_high = high;
            if !(falling && self.holding.load(Ordering::Acquire)) {
                return None;
            }
            s.clocks_seen = s.clocks_seen.saturating_add(1);
            match s.release {
                Some(Release::AfterClocks(k)) if s.clocks_seen >= k => {
                    self.holding.store(false, Ordering::Release);
                    s.free_bus = true;
                    s.sda.clone()
                }
                _ => None,
            }
        });
        // Outside our lock: driving a wire re-enters the net's sinks.
        if let Some(sda) = released {
            sda.drive(Drive::HiZ);
        }
    }

    fn connect_sda(&self, source: WireSource) {
        source.drive(if self.holding() { Drive::Low } else { Drive::HiZ });
        self.with(|s| s.sda = Some(source));
    }
}

/// The controller's view of the stuck line on the transactional bus: it answers no address and, while SDA
/// is held, refuses every bus event (see the module documentation).
#[derive(Debug)]
pub struct StuckSlave {
    line: StuckLine,
}

impl I2cSlave for StuckSlave {
    fn address(&self, _address: Address, _dir: Direction) -> Ack {
        Ack::Nack
    }

    fn write(&self, _byte: u8) -> Ack {
        Ack::Nack
    }

    fn read(&self) -> u8 {
        0xFF
    }

    fn stop(&self) {}

    fn stretching(&self) -> bool {
        let holding = self.line.holding();
        let free_bus = self.line.with(|s| {
            if holding {
                s.stalled_half_periods = s.stalled_half_periods.saturating_add(1);
            }
            std::mem::take(&mut s.free_bus)
        });
        if free_bus && let Some(bus) = self.line.bus.get() {
            // The STOP of the recovery (after its clocks), which clears BUSY (RM0090 §27.6.7). Called by the
            // controller's engine with no lock of the fabric held (`I2cBus::stretching` clones the list).
            bus.stop();
        }
        holding
    }
}

#[derive(Debug)]
struct SclSink {
    line: StuckLine,
}

impl WireSink for SclSink {
    fn set_level(&self, _src: WireId, _line: u32, level: Level) {
        self.line.scl(level.is_high());
    }
}

/// The device: input `scl`, outputs `sda`, `scl-af`, `sda-af`.
#[derive(Debug)]
pub struct Stuck {
    line: StuckLine,
    sink: Arc<SclSink>,
}

impl Stuck {
    pub fn new(line: StuckLine) -> Self {
        Self {
            sink: Arc::new(SclSink { line: line.clone() }),
            line,
        }
    }
}

impl Device for Stuck {
    fn class(&self) -> &'static DeviceClass {
        &CLASS
    }

    fn realize(&self, _ctx: &mut RealizeCtx<'_>) -> Result<()> {
        Ok(())
    }

    fn reset(&self, _kind: ResetKind) {}

    fn connect(&self, port: &str, source: WireSource) -> Result<()> {
        match port {
            "sda" => self.line.connect_sda(source),
            // The I2C peripheral's pad outputs: released (see the module documentation).
            "scl-af" | "sda-af" => {
                source.set(Level::High);
            }
            _ => {
                return Err(Error::Config {
                    at: String::from(CLASS_NAME),
                    message: format!("no output `{port}` (sda, scl-af, sda-af)"),
                });
            }
        }
        Ok(())
    }

    fn sink(&self, port: &str, _sources: &[WireId]) -> Option<SinkPin> {
        (port == "scl").then(|| SinkPin {
            sink: Arc::clone(&self.sink) as Arc<dyn WireSink>,
            line: 0,
        })
    }
}

impl Instance for Stuck {}

/// Which bus an instance belongs to (`bus = "sensors"` or `"deck"`).
pub fn bus_name(props: &Props) -> Result<String> {
    props
        .require("bus")?
        .as_str()
        .map(str::to_string)
        .ok_or_else(|| Error::Config {
            at: String::from(CLASS_NAME),
            message: String::from("`bus` must be a string"),
        })
}

/// The `pil.stuck` device class.
pub static CLASS: DeviceClass = DeviceClass {
    name: CLASS_NAME,
    version: 1,
    summary: "an I2C slave holding SDA low until enough SCL clocks (cfnav PIL)",
    properties: &[PropertySpec {
        name: "bus",
        kind: ValueKind::Str,
        required: true,
        summary: "the named I2C bus it sits on",
    }],
    construct: |_props| Ok(Box::new(Stuck::new(StuckLine::new(None)))),
};

/// What the validator should know about `pil.stuck`.
pub fn schema() -> ClassSchema {
    ClassSchema::new(CLASS_NAME)
        .prop(PropSchema::new("bus", ValueKind::Str).values(&["sensors", "deck"]))
        .port("scl", PortDir::In)
        .port("sda", PortDir::Out)
        .port("scl-af", PortDir::Out)
        .port("sda-af", PortDir::Out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_release_count_parses_and_is_bounded() {
        assert_eq!(Release::parse(None), Ok(Release::AfterClocks(9)));
        assert_eq!(Release::parse(Some("3")), Ok(Release::AfterClocks(3)));
        assert_eq!(Release::parse(Some("never")), Ok(Release::Never));
        assert!(Release::parse(Some("0")).is_err());
        assert!(Release::parse(Some("10")).is_err());
        assert!(Release::parse(Some("x")).is_err());
    }

    #[test]
    fn sda_is_released_on_the_kth_falling_scl_edge_and_the_bus_stalls_until_then() {
        let line = StuckLine::new(Some(Release::AfterClocks(3)));
        let slave = StuckSlave { line: line.clone() };
        assert!(slave.stretching(), "held from power-on: every bus event waits");
        // Rising edges and repeated levels are not clocks.
        line.scl(true);
        line.scl(false);
        line.scl(false);
        line.scl(true);
        line.scl(false);
        assert!(line.holding(), "two clocks of three");
        line.scl(true);
        line.scl(false);
        assert!(
            !line.holding() && !slave.stretching(),
            "released on the third falling edge"
        );
        line.scl(true);
        line.scl(false);
        let s = line.stats();
        assert_eq!(s.clocks_seen, 3, "edges after the release are not counted");
        assert_eq!(slave.address(Address::Seven(0x18), Direction::Write), Ack::Nack);
    }

    #[test]
    fn a_latched_slave_never_lets_go_and_a_healthy_line_never_holds() {
        let latched = StuckLine::new(Some(Release::Never));
        for _ in 0..100 {
            latched.scl(false);
            latched.scl(true);
        }
        assert!(latched.holding());
        assert_eq!(latched.stats().clocks_seen, 100);
        let healthy = StuckLine::new(None);
        healthy.scl(false);
        assert!(!healthy.holding() && !(StuckSlave { line: healthy.clone() }).stretching());
        assert_eq!(healthy.stats().clocks_seen, 0);
    }

    #[test]
    fn busy_is_open_while_held_and_closed_by_the_first_bus_event_after_the_release() {
        let bus = Arc::new(I2cBus::new());
        let line = StuckLine::new(Some(Release::AfterClocks(1)));
        line.hold_bus(&bus).unwrap();
        assert!(bus.state().is_busy(), "SR2.BUSY while SDA is low");
        assert!(bus.stretching());
        line.scl(false);
        assert!(bus.state().is_busy(), "still busy until a bus event sees the release");
        assert!(!bus.stretching());
        assert!(!bus.state().is_busy(), "the recovery's STOP freed the bus");
    }
}
