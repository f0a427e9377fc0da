//! The Flow deck v2's PMW3901 optical-flow sensor on SPI1 ([`Pmw3901`], an rsemu [`SpiSlave`]), and
//! `pil.cs`, the chip-select input that connects it: the image drives PB4 as a GPIO (embassy's SPI uses
//! software NSS), which rsemu's `stm32.spi` does not see, so `pil.cs` watches PB4's net and selects chip
//! select 0 of the "flowdeck" SPI bus while the pin is low.
//!
//! Job: answer the power-up sequence and the motion burst as the chip does, with
//! motion the host adds from the simulator's truth ([`Pmw3901::add_motion`]).
//!
//! Protocol (bitcraze `pmw3901.c`, PixArt PMW3901MB datasheet; the firmware's `cfnav::drivers::pmw3901`
//! cites both): each access starts with CS falling; the first byte is the register address, bit 7 set for
//! a write, then one value byte (a write) or the register's value clocked out (a read). Motion_Burst (0x16)
//! clocks out 12 bytes: Motion, Observation, Delta_X_L/H, Delta_Y_L/H, SQUAL, Raw_Data_Sum,
//! Maximum_Raw_Data, Minimum_Raw_Data, Shutter_Upper, Shutter_Lower; reading it (or Motion, 0x02, then the
//! deltas) resets the accumulated deltas. Product_ID (0x00) = 0x49, Inverse_Product_ID (0x5F) = 0xB6.
//! Power_Up_Reset (0x3A ← 0x5A) resets the registers. Until the image has written the vendor's
//! performance-optimisation table (it ends with 0x7F ← 0x00 … 0x5A ← 0x10, 0x54 ← 0x00) the model reports
//! no motion (Motion bit 7 clear, SQUAL 0): a driver that skips the power-up sequence sees no flow, as on
//! the chip, whose tracking is not configured then. A deck that is not fitted leaves MISO floating high
//! (every byte 0xFF).
//!
//! Axes: the firmware maps `dpixel_x = −Delta_Y`, `dpixel_y = −Delta_X`; [`Pmw3901::add_motion`] takes body
//! `dpixel` counts (as the simulator's `FlowSensor` makes them) and stores the chip's deltas.
//!
//! Non-goals: the in-transaction timing (tSRAD) is not checked; no frame capture; no noise (the host adds
//! it).

use std::sync::{Arc, Mutex, OnceLock};

use rsemu::bus::spi::{ChipSelect, Format, SpiBus, SpiSlave};
use rsemu::core::device::{Device, DeviceClass, RealizeCtx, ResetKind, SinkPin};
use rsemu::core::error::Result;
use rsemu::core::wire::{Level, WireId, WireSink};
use rsemu::machine::Instance;
use rsemu::machine::validate::{ClassSchema, PortDir};

/// Product_ID.
pub const PRODUCT_ID: u8 = 0x49;
/// Motion byte with motion and the frame valid bits (what stock accepts).
pub const MOTION_VALID: u8 = 0xB0;
/// SQUAL the model reports over a textured floor.
pub const SQUAL: u8 = 0x60;

#[derive(Debug)]
struct State {
    fitted: bool,
    regs: [u8; 0x80],
    selected: bool,
    /// Bytes of the current access so far.
    byte_in_frame: u32,
    address: u8,
    /// Accumulated deltas (chip axes).
    delta: [i32; 2],
    /// The vendor table's last write was seen since the last power-up reset.
    configured: bool,
    /// The simulator's flow model sees texture at a usable height ([`Pmw3901::set_tracking`]).
    tracking: bool,
    burst: [u8; 12],
}

/// Counters for the report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct FlowStats {
    pub selects: u32,
    pub register_writes: u32,
    pub register_reads: u32,
    pub bursts: u32,
    pub power_up_resets: u32,
    pub configured: bool,
}

/// The PMW3901.
#[derive(Debug)]
pub struct Pmw3901 {
    state: Mutex<State>,
    stats: Mutex<FlowStats>,
}

impl Pmw3901 {
    pub fn new(fitted: bool) -> Self {
        let mut s = State {
            fitted,
            regs: [0; 0x80],
            selected: false,
            byte_in_frame: 0,
            address: 0,
            delta: [0; 2],
            configured: false,
            tracking: true,
            burst: [0; 12],
        };
        power_up(&mut s);
        Self {
            state: Mutex::new(s),
            stats: Mutex::new(FlowStats::default()),
        }
    }

    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        f(&mut self.state.lock().unwrap_or_else(|e| e.into_inner()))
    }

    fn count(&self, f: impl FnOnce(&mut FlowStats)) {
        f(&mut self.stats.lock().unwrap_or_else(|e| e.into_inner()));
    }

    /// Adds body-frame pixel counts (`dpixel_x`, `dpixel_y`) seen since the last call.
    pub fn add_motion(&self, dpixel: [f32; 2]) {
        self.with(|s| {
            if !s.configured {
                return;
            }
            // dpixel_x = −Delta_Y, dpixel_y = −Delta_X.
            s.delta[0] -= dpixel[1].round() as i32;
            s.delta[1] -= dpixel[0].round() as i32;
        });
    }

    /// Whether the chip tracks (the simulator's flow model says its reading is valid: height within the
    /// sensor's range, light); while it does not, the burst reports no motion and SQUAL 0.
    pub fn set_tracking(&self, tracking: bool) {
        self.with(|s| s.tracking = tracking);
    }

    /// The deck stops answering (`--fault flow-deck-lost`): from now on MISO floats high, as when the deck
    /// is not fitted.
    pub fn unplug(&self) {
        self.with(|s| s.fitted = false);
    }

    pub fn stats(&self) -> FlowStats {
        let mut st = *self.stats.lock().unwrap_or_else(|e| e.into_inner());
        st.configured = self.with(|s| s.configured);
        st
    }
}

fn power_up(s: &mut State) {
    s.regs = [0; 0x80];
    s.regs[0x00] = PRODUCT_ID;
    s.regs[0x01] = 0x00; // Revision_ID
    s.regs[0x5F] = !PRODUCT_ID;
    s.delta = [0; 2];
    s.configured = false;
}

fn clamp16(v: i32) -> [u8; 2] {
    (v.clamp(i32::from(i16::MIN), i32::from(i16::MAX)) as i16).to_le_bytes()
}

impl SpiSlave for Pmw3901 {
    fn format(&self) -> Format {
        Format::DEFAULT
    }

    fn select(&self, selected: bool) {
        if selected {
            self.count(|c| c.selects += 1);
        }
        self.with(|s| {
            s.selected = selected;
            s.byte_in_frame = 0;
        });
    }

    fn transfer(&self, mosi: u32) -> u32 {
        let byte = mosi as u8;
        let mut event = None;
        let out = self.with(|s| {
            if !s.fitted {
                return 0xFF;
            }
            let n = s.byte_in_frame;
            s.byte_in_frame += 1;
            if n == 0 {
                s.address = byte;
                if byte & 0x80 == 0 {
                    let reg = byte & 0x7F;
                    if reg == 0x16 {
                        let tracking = s.configured && s.tracking;
                        let motion = if tracking { MOTION_VALID } else { 0x20 };
                        let dx = clamp16(s.delta[0]);
                        let dy = clamp16(s.delta[1]);
                        let squal = if tracking { SQUAL } else { 0 };
                        s.burst = [
                            motion, 0xBF, dx[0], dx[1], dy[0], dy[1], squal, 0x40, 0x80, 0x10, 0x00, 0x40,
                        ];
                        s.delta = [0; 2];
                        event = Some(2);
                    } else {
                        event = Some(1);
                    }
                }
                return 0x00;
            }
            let reg = s.address & 0x7F;
            if s.address & 0x80 != 0 {
                if n == 1 {
                    s.regs[usize::from(reg)] = byte;
                    event = Some(0);
                    if reg == 0x3A && byte == 0x5A {
                        power_up(s);
                        event = Some(3);
                    }
                    // The last write of the vendor table (bank 0: 0x54 ← 0x00 after 0x5A ← 0x10).
                    if reg == 0x54 && byte == 0x00 && s.regs[0x5A] == 0x10 && s.regs[0x7F] == 0x00 {
                        s.configured = true;
                    }
                }
                return 0x00;
            }
            if reg == 0x16 {
                let i = (n - 1) as usize;
                return s.burst.get(i).copied().unwrap_or(0x00);
            }
            match reg {
                0x02 => {
                    if s.configured && s.delta != [0, 0] {
                        0x80
                    } else {
                        0x00
                    }
                }
                0x03 => clamp16(s.delta[0])[0],
                0x04 => clamp16(s.delta[0])[1],
                0x05 => clamp16(s.delta[1])[0],
                0x06 => {
                    let v = clamp16(s.delta[1])[1];
                    s.delta = [0; 2];
                    v
                }
                r => s.regs[usize::from(r)],
            }
        });
        match event {
            Some(0) => self.count(|c| c.register_writes += 1),
            Some(1) => self.count(|c| c.register_reads += 1),
            Some(2) => self.count(|c| c.bursts += 1),
            Some(3) => self.count(|c| {
                c.register_writes += 1;
                c.power_up_resets += 1
            }),
            _ => {}
        }
        u32::from(out)
    }

    fn peek(&self) -> u32 {
        0xFF
    }
}

// ---- pil.cs: a GPIO net → an SPI bus's chip select ----

/// The class name a machine file writes.
pub const CS_CLASS_NAME: &str = "pil.cs";

/// Where the selection goes (set by the host before the machine is built).
#[derive(Debug, Clone, Default)]
pub struct CsTarget(Arc<OnceLock<Arc<SpiBus>>>);

impl CsTarget {
    pub fn set(&self, bus: Arc<SpiBus>) {
        let _ = self.0.set(bus);
    }
}

#[derive(Debug)]
struct CsSink {
    target: CsTarget,
}

impl WireSink for CsSink {
    fn set_level(&self, _src: WireId, _line: u32, level: Level) {
        if let Some(bus) = self.target.0.get() {
            // Active low.
            let want = level.is_low().then_some(ChipSelect(0));
            if bus.selected() != want {
                bus.select(want);
            }
        }
    }
}

/// The device: one input pin `in`.
#[derive(Debug)]
pub struct Cs {
    sink: Arc<CsSink>,
}

impl Cs {
    pub fn new(target: CsTarget) -> Self {
        Self {
            sink: Arc::new(CsSink { target }),
        }
    }
}

impl Device for Cs {
    fn class(&self) -> &'static DeviceClass {
        &CS_CLASS
    }

    fn realize(&self, _ctx: &mut RealizeCtx<'_>) -> Result<()> {
        Ok(())
    }

    fn reset(&self, _kind: ResetKind) {}

    fn sink(&self, port: &str, _sources: &[WireId]) -> Option<SinkPin> {
        (port == "in").then(|| SinkPin {
            sink: Arc::clone(&self.sink) as Arc<dyn WireSink>,
            line: 0,
        })
    }
}

impl Instance for Cs {}

/// The `pil.cs` device class.
pub static CS_CLASS: DeviceClass = DeviceClass {
    name: CS_CLASS_NAME,
    version: 1,
    summary: "a GPIO net driving an SPI bus's chip select 0, active low (cfnav PIL)",
    properties: &[],
    construct: |_props| Ok(Box::new(Cs::new(CsTarget::default()))),
};

/// What the validator should know about `pil.cs`.
pub fn cs_schema() -> ClassSchema {
    ClassSchema::new(CS_CLASS_NAME).port("in", PortDir::In)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn access(dev: &Pmw3901, bytes: &[u8]) -> Vec<u8> {
        dev.select(true);
        let out = bytes.iter().map(|&b| dev.transfer(u32::from(b)) as u8).collect();
        dev.select(false);
        out
    }

    fn configure(dev: &Pmw3901) {
        for (r, v) in [(0x7F, 0x00), (0x5A, 0x10), (0x54, 0x00)] {
            access(dev, &[r | 0x80, v]);
        }
    }

    #[test]
    fn identity_reset_and_burst_with_the_firmware_axis_mapping() {
        let dev = Pmw3901::new(true);
        assert_eq!(access(&dev, &[0x00, 0x00])[1], 0x49);
        assert_eq!(access(&dev, &[0x5F, 0x00])[1], 0xB6);
        // Not configured: no motion reported.
        dev.add_motion([10.0, 0.0]);
        let b = access(&dev, &[0x16; 13]);
        assert_eq!(b[1] & 0x80, 0);
        configure(&dev);
        dev.add_motion([12.0, -5.0]);
        let b: [u8; 12] = access(&dev, &[0x16; 13])[1..].try_into().unwrap();
        let burst = cfnav::drivers::pmw3901::MotionBurst::parse(&b);
        assert!(burst.is_valid());
        let sample = burst.to_sample(0.01);
        assert_eq!((sample.dpixel_x, sample.dpixel_y), (12, -5));
        // Reading the burst reset the deltas.
        let b: [u8; 12] = access(&dev, &[0x16; 13])[1..].try_into().unwrap();
        let s = cfnav::drivers::pmw3901::MotionBurst::parse(&b).to_sample(0.01);
        assert_eq!((s.dpixel_x, s.dpixel_y), (0, 0));
        // Not tracking (too low or dark in the simulator): no valid motion.
        dev.set_tracking(false);
        let b: [u8; 12] = access(&dev, &[0x16; 13])[1..].try_into().unwrap();
        assert!(!cfnav::drivers::pmw3901::MotionBurst::parse(&b).is_valid());
        dev.set_tracking(true);
        // Power_Up_Reset forgets the configuration.
        access(&dev, &[0x3A | 0x80, 0x5A]);
        assert!(!dev.stats().configured);
    }

    #[test]
    fn an_absent_deck_reads_all_ones() {
        let dev = Pmw3901::new(false);
        assert_eq!(access(&dev, &[0x00, 0x00])[1], 0xFF);
    }
}
