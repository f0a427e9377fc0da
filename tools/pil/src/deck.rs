//! The deck bus (I2C1) sensors of the emulated Crazyflie: the Multi-ranger deck (a PCA9534 expander at 0x20
//! whose pins hold the XSHUT lines of five VL53L1x rangers) and the Flow deck v2's VL53L1x height ranger
//! (no XSHUT: powered from power-on), as one [`I2cSlave`] so the expander's pins can power the rangers.
//!
//! Job: answer the image's bring-up and reads the way the chips do, with ranges the
//! host sets from the simulator's world ([`DeckSensors::set_ranges`]) and time the host advances
//! ([`DeckSensors::advance`]).
//!
//! * PCA9534 (NXP PCA9534 datasheet, §6.2–6.3): a command byte selects register 0 (input), 1 (output, reset
//!   0xFF), 2 (polarity inversion, reset 0x00) or 3 (configuration, reset 0xFF = all inputs); the next
//!   written bytes go to that register (no auto-increment), reads repeat it. Writes to the input register
//!   are ignored. A pin configured as input floats high through the deck's pull-ups, so at power-on every
//!   XSHUT is high and all five rangers boot at 0x29 together (why the firmware holds them in reset first).
//! * VL53L1x (ST VL53L1X datasheet DS12385 and the ULD register map the firmware cites): 16-bit big-endian
//!   register index with auto-increment; NACKs its address while powered off and for
//!   [`VL53_BOOT_NS`] after power-up (tBOOT 1.2 ms); FIRMWARE__SYSTEM_STATUS (0xE5) bit 0 after boot;
//!   IDENTIFICATION__MODEL_ID 0xEACC at 0x010F; I2C_SLAVE__DEVICE_ADDRESS (0x0001) moves it at once and is
//!   forgotten on power-off; SYSTEM__MODE_START (0x87) 0x40 starts continuous ranging, 0x00 stops; one result
//!   every inter-measurement period (SYSTEM__INTERMEASUREMENT_PERIOD at 0x6C divided by
//!   RESULT__OSC_CALIBRATE_VAL · 1.075, the ULD's formula, at least [`MIN_PERIOD_NS`]), written to
//!   RESULT__RANGE_STATUS (0x89: 9 = valid, 4 = signal fail past [`MAX_RANGE_M`]) and
//!   RESULT__FINAL_CROSSTALK_CORRECTED_RANGE_MM_SD0 (0x96) and flagged on GPIO__TIO_HV_STATUS (0x31) bit 0
//!   at the polarity GPIO_HV_MUX__CTRL (0x30) bit 4 selects. A result holds the range the host set half a
//!   timing budget before it is flagged: the chip integrates over its budget (RANGE_CONFIG__TIMEOUT_MACROP_A
//!   and _B at 0x5E and 0x61, the ULD's table; the whole period if they hold no budget of the table) and
//!   reports at the end (the host sets ranges every 1 ms). A result that is not cleared
//!   (SYSTEM__INTERRUPT_CLEAR 0x86 = 0x01) stays: the next ones are not written over it (stale data, as a
//!   driver that forgets the clear would see). Two chips at one address answer together (wired-AND of
//!   their bytes, as on the open-drain bus).
//!
//! Non-goals: the budget's effect on range noise (the period alone sets the rate), ROI, offsets, noise (the host
//! adds the simulator's range noise before [`DeckSensors::set_ranges`]).
//!
//! Units: ranges in metres from the host, millimetres on the bus; time in ns of virtual time.

use std::sync::Mutex;

use rsemu::bus::i2c::{Ack, Address, Direction, I2cSlave};

/// The expander's 7-bit address (docs/hardware.md §2; `cfnav::drivers::pca95x4::DEFAULT_ADDRESS`).
pub const EXPANDER_ADDRESS: u8 = 0x20;
/// A VL53L1x's address after power-up.
pub const VL53_DEFAULT_ADDRESS: u8 = 0x29;
/// Boot time after power-up (DS12385 tBOOT, 1.2 ms max).
pub const VL53_BOOT_NS: u64 = 1_200_000;
/// The fastest ranging period modelled (the shortest timing budget, 20 ms).
pub const MIN_PERIOD_NS: u64 = 20_000_000;
/// Beyond this a VL53L1x in long mode reports a signal failure (DS12385: 4 m in the dark).
pub const MAX_RANGE_M: f32 = 4.0;
/// RESULT__OSC_CALIBRATE_VAL the model reports: chosen so the default configuration's inter-measurement
/// value 0x0F89 gives ≈ 100 ms, the ULD default (`3977 / (37 · 1.075)` = 100.0 ms).
pub const OSC_CALIBRATE_VAL: u16 = 37;

/// The ranger indices: the Multi-ranger's five in the firmware's bring-up order, then the Flow deck's.
pub const FRONT: usize = 0;
pub const BACK: usize = 1;
pub const UP: usize = 2;
pub const LEFT: usize = 3;
pub const RIGHT: usize = 4;
pub const DOWN: usize = 5;

/// The expander pin (bit) of each Multi-ranger ranger's XSHUT (stock `multiranger.c`: P4 front, P1 back,
/// P0 up, P6 left, P2 right).
const XSHUT_BIT: [u8; 5] = [1 << 4, 1 << 1, 1 << 0, 1 << 6, 1 << 2];

/// What is fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fitted {
    pub multiranger: bool,
    pub flow: bool,
}

/// Counters for the report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct DeckStats {
    pub expander_writes: u32,
    pub address_changes: u32,
    pub ranging_starts: u32,
    /// Results written (per ranger).
    pub results: [u32; 6],
    /// Results not written because the previous one was not cleared.
    pub stale_skips: u32,
    /// Transfers addressed to a booting ranger (NACKed).
    pub nacked_while_booting: u32,
}

#[derive(Debug, Clone)]
struct Vl53 {
    powered: bool,
    powered_at_ns: u64,
    address: u8,
    regs: Box<[u8; 0x200]>,
    index: u16,
    index_bytes: u8,
    addressed: bool,
    ranging: bool,
    next_result_ns: u64,
    ready: bool,
    /// The range of the result being integrated, taken at the middle of its ranging period; `None` until
    /// then (`Some(None)`: no target at that instant).
    mid_period_range_m: Option<Option<f32>>,
}

impl Vl53 {
    fn new() -> Self {
        let mut v = Self {
            powered: false,
            powered_at_ns: 0,
            address: VL53_DEFAULT_ADDRESS,
            regs: Box::new([0; 0x200]),
            index: 0,
            index_bytes: 0,
            addressed: false,
            ranging: false,
            next_result_ns: 0,
            ready: false,
            mid_period_range_m: None,
        };
        v.reset_registers();
        v
    }

    fn reset_registers(&mut self) {
        self.regs.fill(0);
        self.regs[0x0001] = VL53_DEFAULT_ADDRESS;
        self.regs[0x0030] = 0x01; // GPIO_HV_MUX__CTRL: active high (the default configuration's value)
        self.regs[0x006C..0x0070].copy_from_slice(&0x0000_0F89u32.to_be_bytes());
        self.regs[0x00DE..0x00E0].copy_from_slice(&OSC_CALIBRATE_VAL.to_be_bytes());
        self.regs[0x00E5] = 0x01; // FIRMWARE__SYSTEM_STATUS: booted (readable only once booted)
        self.regs[0x010F] = 0xEA;
        self.regs[0x0110] = 0xCC;
        self.address = VL53_DEFAULT_ADDRESS;
        self.ranging = false;
        self.ready = false;
    }

    fn set_power(&mut self, on: bool, now_ns: u64) {
        if on && !self.powered {
            self.reset_registers();
            self.powered_at_ns = now_ns;
        }
        if !on {
            self.addressed = false;
        }
        self.powered = on;
    }

    fn booted(&self, now_ns: u64) -> bool {
        self.powered && now_ns >= self.powered_at_ns + VL53_BOOT_NS
    }

    fn period_ns(&self) -> u64 {
        let imp = u32::from_be_bytes([self.regs[0x6C], self.regs[0x6D], self.regs[0x6E], self.regs[0x6F]]);
        let osc = u64::from(u16::from_be_bytes([self.regs[0xDE], self.regs[0xDF]]) & 0x3FF).max(1);
        // ms = imp / (osc · 1.075)
        let ns = u64::from(imp) * 1_000_000_000 / (osc * 1075);
        ns.max(MIN_PERIOD_NS)
    }

    /// The timing budget the image set in RANGE_CONFIG__TIMEOUT_MACROP_A (0x5E) and _B (0x61), both
    /// big-endian, decoded with the ULD's table (`cfnav::drivers::vl53l1x::TimingBudget`, either distance
    /// mode), ns; `None` for a pair outside the table (the model then integrates over the whole period).
    fn budget_ns(&self) -> Option<u64> {
        use cfnav::drivers::vl53l1x::{DistanceMode, TimingBudget};
        let a = u16::from_be_bytes([self.regs[0x5E], self.regs[0x5F]]);
        let b = u16::from_be_bytes([self.regs[0x61], self.regs[0x62]]);
        let budgets = [
            TimingBudget::Ms15,
            TimingBudget::Ms20,
            TimingBudget::Ms33,
            TimingBudget::Ms50,
            TimingBudget::Ms100,
            TimingBudget::Ms200,
            TimingBudget::Ms500,
        ];
        budgets
            .into_iter()
            .find(|t| {
                [DistanceMode::Short, DistanceMode::Long]
                    .into_iter()
                    .any(|m| t.timeout_macrop_a_b(m) == Some((a, b)))
            })
            .map(|t| u64::from(t.ms()) * 1_000_000)
    }

    fn active_high(&self) -> bool {
        self.regs[0x30] & 0x10 == 0
    }

    fn status_byte(&self) -> u8 {
        let level = self.ready == self.active_high();
        (self.regs[0x31] & !0x01) | u8::from(level)
    }

    fn reg_read(&self, index: u16) -> u8 {
        match index {
            0x0031 => self.status_byte(),
            i if usize::from(i) < self.regs.len() => self.regs[usize::from(i)],
            _ => 0x00,
        }
    }

    /// A register write; returns whether it changed the address.
    fn reg_write(&mut self, index: u16, value: u8, now_ns: u64, stats: &mut DeckStats) {
        match index {
            0x0001 => {
                self.address = value & 0x7F;
                self.regs[0x0001] = value & 0x7F;
                stats.address_changes += 1;
            }
            0x0086 if value & 0x01 != 0 => self.ready = false,
            0x0086 => {}
            0x0087 => {
                self.regs[0x87] = value;
                if value == 0x40 {
                    if !self.ranging {
                        stats.ranging_starts += 1;
                        self.next_result_ns = now_ns + self.period_ns();
                    }
                    self.ranging = true;
                } else if value == 0x00 {
                    self.ranging = false;
                }
            }
            // Read-only: results, identification, status.
            0x0089..=0x00DF | 0x00E5 | 0x010F..=0x0110 => {}
            i if usize::from(i) < self.regs.len() => self.regs[usize::from(i)] = value,
            _ => {}
        }
    }

    fn advance(&mut self, now_ns: u64, range_m: Option<f32>, index: usize, stats: &mut DeckStats) {
        if !self.powered || !self.ranging {
            self.mid_period_range_m = None;
            return;
        }
        let period = self.period_ns();
        while now_ns >= self.next_result_ns {
            // A clock step past the middle of the period (only in tests: the host advances 1 ms at a time)
            // takes the range as it is now.
            let range_m = self.mid_period_range_m.take().unwrap_or(range_m);
            if self.ready {
                stats.stale_skips += 1;
            } else {
                let (status, mm) = match range_m {
                    Some(m) if m.is_finite() && (0.0..=MAX_RANGE_M).contains(&m) => (9u8, (m * 1000.0).round() as u16),
                    _ => (4u8, 0u16),
                };
                self.regs[0x89] = status;
                self.regs[0x96..0x98].copy_from_slice(&mm.to_be_bytes());
                self.ready = true;
                stats.results[index] += 1;
            }
            self.next_result_ns += period;
        }
        // The chip integrates the returns over its timing budget (which the period bounds) and reports when
        // it ends: a moving drone's result is the range half a budget before it is flagged.
        let integration = self.budget_ns().unwrap_or(period).min(period);
        if self.mid_period_range_m.is_none() && now_ns + integration / 2 >= self.next_result_ns {
            self.mid_period_range_m = Some(range_m);
        }
    }
}

#[derive(Debug)]
struct State {
    fitted: Fitted,
    now_ns: u64,
    expander_regs: [u8; 4],
    expander_pointer: u8,
    expander_expect_command: bool,
    expander_addressed: bool,
    rangers: Vec<Vl53>,
    ranges_m: [Option<f32>; 6],
    stats: DeckStats,
}

impl State {
    /// The level of each expander pin: an output drives its register bit, an input floats high.
    fn pin_levels(&self) -> u8 {
        let config = self.expander_regs[3];
        (self.expander_regs[1] & !config) | config
    }

    fn update_power(&mut self) {
        if !self.fitted.multiranger {
            return;
        }
        let pins = self.pin_levels();
        let now = self.now_ns;
        for (i, bit) in XSHUT_BIT.iter().enumerate() {
            self.rangers[i].set_power(pins & bit != 0, now);
        }
    }
}

/// The deck bus sensors.
#[derive(Debug)]
pub struct DeckSensors {
    state: Mutex<State>,
}

impl DeckSensors {
    pub fn new(fitted: Fitted) -> Self {
        let mut rangers = vec![Vl53::new(); 6];
        if fitted.flow {
            rangers[DOWN].set_power(true, 0);
        }
        let mut state = State {
            fitted,
            now_ns: 0,
            expander_regs: [0xFF, 0xFF, 0x00, 0xFF],
            expander_pointer: 0,
            expander_expect_command: true,
            expander_addressed: false,
            rangers,
            ranges_m: [Some(2.0), Some(2.0), Some(2.0), Some(2.0), Some(2.0), Some(0.0)],
            stats: DeckStats::default(),
        };
        state.update_power();
        Self {
            state: Mutex::new(state),
        }
    }

    fn with<R>(&self, f: impl FnOnce(&mut State) -> R) -> R {
        f(&mut self.state.lock().unwrap_or_else(|e| e.into_inner()))
    }

    /// The true ranges (m) each ranger sees now: [front, back, up, left, right, down]; `None` = no target.
    pub fn set_ranges(&self, ranges_m: [Option<f32>; 6]) {
        self.with(|s| s.ranges_m = ranges_m);
    }

    /// Moves the sensors' clock to `now_ns` and writes the results that came due.
    pub fn advance(&self, now_ns: u64) {
        self.with(|s| {
            s.now_ns = now_ns;
            let ranges = s.ranges_m;
            let State { rangers, stats, .. } = s;
            for (i, r) in rangers.iter_mut().enumerate() {
                r.advance(now_ns, ranges[i], i, stats);
            }
        });
    }

    /// The Flow deck's height ranger leaves the bus (`--fault flow-deck-lost`): it no longer acknowledges
    /// its address.
    pub fn unplug_flow(&self) {
        self.with(|s| {
            s.fitted.flow = false;
            let now = s.now_ns;
            s.rangers[DOWN].set_power(false, now);
        });
    }

    /// The Multi-ranger leaves the bus (`--fault multiranger-lost`): its expander and its five rangers no
    /// longer acknowledge their addresses (the Flow deck's ranger stays).
    pub fn unplug_multiranger(&self) {
        self.with(|s| {
            s.fitted.multiranger = false;
            let now = s.now_ns;
            for (i, r) in s.rangers.iter_mut().enumerate() {
                if i != DOWN {
                    r.set_power(false, now);
                }
            }
        });
    }

    pub fn stats(&self) -> DeckStats {
        self.with(|s| s.stats)
    }

    /// Each ranger's current address if powered (for the report).
    pub fn addresses(&self) -> [Option<u8>; 6] {
        self.with(|s| {
            let mut out = [None; 6];
            for (o, r) in out.iter_mut().zip(&s.rangers) {
                *o = r.powered.then_some(r.address);
            }
            out
        })
    }
}

impl I2cSlave for DeckSensors {
    fn address(&self, address: Address, dir: Direction) -> Ack {
        let Address::Seven(a) = address else {
            return Ack::Nack;
        };
        self.with(|s| {
            let now = s.now_ns;
            let mut ack = false;
            s.expander_addressed = s.fitted.multiranger && a == EXPANDER_ADDRESS;
            if s.expander_addressed {
                ack = true;
                if dir == Direction::Write {
                    s.expander_expect_command = true;
                }
            }
            let mut booting = false;
            for r in s.rangers.iter_mut() {
                r.addressed = false;
                if !r.powered || r.address != a {
                    continue;
                }
                if !r.booted(now) {
                    booting = true;
                    continue;
                }
                r.addressed = true;
                ack = true;
                if dir == Direction::Write {
                    r.index_bytes = 0;
                }
            }
            if booting && !ack {
                s.stats.nacked_while_booting += 1;
            }
            if ack { Ack::Ack } else { Ack::Nack }
        })
    }

    fn write(&self, byte: u8) -> Ack {
        self.with(|s| {
            let now = s.now_ns;
            let mut ack = false;
            if s.expander_addressed {
                ack = true;
                if s.expander_expect_command {
                    s.expander_pointer = byte & 0x03;
                    s.expander_expect_command = false;
                } else {
                    let p = usize::from(s.expander_pointer);
                    if p != 0 {
                        s.expander_regs[p] = byte;
                        s.stats.expander_writes += 1;
                        s.update_power();
                    }
                }
            }
            let State { rangers, stats, .. } = s;
            for r in rangers.iter_mut().filter(|r| r.addressed) {
                ack = true;
                match r.index_bytes {
                    0 => {
                        r.index = u16::from(byte) << 8;
                        r.index_bytes = 1;
                    }
                    1 => {
                        r.index |= u16::from(byte);
                        r.index_bytes = 2;
                    }
                    _ => {
                        let i = r.index;
                        r.reg_write(i, byte, now, stats);
                        r.index = r.index.wrapping_add(1);
                    }
                }
            }
            if ack { Ack::Ack } else { Ack::Nack }
        })
    }

    fn read(&self) -> u8 {
        self.with(|s| {
            let mut byte = 0xFFu8;
            if s.expander_addressed {
                byte &= match s.expander_pointer {
                    0 => s.pin_levels() ^ s.expander_regs[2],
                    p => s.expander_regs[usize::from(p)],
                };
            }
            for r in s.rangers.iter().filter(|r| r.addressed) {
                byte &= r.reg_read(r.index);
            }
            byte
        })
    }

    fn read_ack(&self, _ack: Ack) {
        self.with(|s| {
            for r in s.rangers.iter_mut().filter(|r| r.addressed) {
                r.index = r.index.wrapping_add(1);
            }
        });
    }

    fn stop(&self) {
        self.with(|s| {
            s.expander_addressed = false;
            for r in s.rangers.iter_mut() {
                r.addressed = false;
            }
        });
    }

    fn peek(&self) -> u8 {
        self.read()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dev: &DeckSensors, addr: u8, bytes: &[u8]) -> bool {
        if dev.address(Address::Seven(addr), Direction::Write) == Ack::Nack {
            dev.stop();
            return false;
        }
        let ok = bytes.iter().all(|&b| dev.write(b) == Ack::Ack);
        dev.stop();
        ok
    }

    fn read16(dev: &DeckSensors, addr: u8, index: u16, n: usize) -> Option<Vec<u8>> {
        if dev.address(Address::Seven(addr), Direction::Write) == Ack::Nack {
            dev.stop();
            return None;
        }
        let [hi, lo] = index.to_be_bytes();
        dev.write(hi);
        dev.write(lo);
        assert_eq!(dev.address(Address::Seven(addr), Direction::Read), Ack::Ack);
        let out = (0..n)
            .map(|_| {
                let b = dev.read();
                dev.read_ack(Ack::Ack);
                b
            })
            .collect();
        dev.stop();
        Some(out)
    }

    #[test]
    fn the_multiranger_rangers_power_from_the_expander_and_move_address() {
        let dev = DeckSensors::new(Fitted {
            multiranger: true,
            flow: false,
        });
        dev.advance(2_000_000);
        // All five boot at 0x29 (inputs float high): their model ids read together.
        assert_eq!(read16(&dev, 0x29, 0x010F, 2), Some(vec![0xEA, 0xCC]));
        // Hold all in reset: output 0 on the five pins, then those pins as outputs.
        assert!(write(&dev, EXPANDER_ADDRESS, &[0x01, 0x00]));
        assert!(write(&dev, EXPANDER_ADDRESS, &[0x03, !0x57]));
        assert_eq!(read16(&dev, 0x29, 0x00E5, 1), None, "nothing at 0x29 in reset");
        // Release front (P4): it NACKs while booting, then answers; move it to 0x6B.
        assert!(write(&dev, EXPANDER_ADDRESS, &[0x01, 0x10]));
        assert_eq!(read16(&dev, 0x29, 0x00E5, 1), None, "booting");
        dev.advance(4_000_000);
        assert_eq!(read16(&dev, 0x29, 0x00E5, 1), Some(vec![0x01]));
        assert!(write(&dev, 0x29, &[0x00, 0x01, 0x6B]));
        assert_eq!(read16(&dev, 0x29, 0x00E5, 1), None);
        assert_eq!(read16(&dev, 0x6B, 0x010F, 2), Some(vec![0xEA, 0xCC]));
        // Reset forgets the address.
        assert!(write(&dev, EXPANDER_ADDRESS, &[0x01, 0x00]));
        dev.advance(10_000_000);
        assert!(write(&dev, EXPANDER_ADDRESS, &[0x01, 0x10]));
        dev.advance(12_000_000);
        assert_eq!(read16(&dev, 0x6B, 0x00E5, 1), None);
        assert_eq!(read16(&dev, 0x29, 0x00E5, 1), Some(vec![0x01]));
    }

    #[test]
    fn a_ranger_ranges_at_its_period_and_keeps_an_uncleared_result() {
        let dev = DeckSensors::new(Fitted {
            multiranger: false,
            flow: true,
        });
        let mut ranges = [None; 6];
        ranges[DOWN] = Some(0.8);
        dev.set_ranges(ranges);
        dev.advance(2_000_000);
        // 25 ms: 25 · 37 · 1.075 = 994.375 → 994 (the ULD's truncation).
        assert!(write(&dev, 0x29, &[0x00, 0x6C, 0, 0, 0x03, 0xE2]));
        assert!(write(&dev, 0x29, &[0x00, 0x87, 0x40]));
        assert_eq!(read16(&dev, 0x29, 0x0031, 1), Some(vec![0x00]), "not ready yet");
        dev.advance(2_000_000 + 24_000_000);
        assert_eq!(read16(&dev, 0x29, 0x0031, 1), Some(vec![0x00]));
        dev.advance(2_000_000 + 25_000_000);
        assert_eq!(read16(&dev, 0x29, 0x0031, 1), Some(vec![0x01]));
        assert_eq!(read16(&dev, 0x29, 0x0089, 1), Some(vec![9]));
        assert_eq!(read16(&dev, 0x29, 0x0096, 2), Some(800u16.to_be_bytes().to_vec()));
        // Not cleared: the next result does not overwrite it.
        ranges[DOWN] = Some(1.5);
        dev.set_ranges(ranges);
        dev.advance(2_000_000 + 50_000_000);
        assert_eq!(read16(&dev, 0x29, 0x0096, 2), Some(800u16.to_be_bytes().to_vec()));
        assert_eq!(dev.stats().stale_skips, 1);
        assert!(write(&dev, 0x29, &[0x00, 0x86, 0x01]));
        dev.advance(2_000_000 + 75_000_000);
        assert_eq!(read16(&dev, 0x29, 0x0096, 2), Some(1500u16.to_be_bytes().to_vec()));
        // Out of range: signal fail.
        ranges[DOWN] = Some(5.0);
        dev.set_ranges(ranges);
        assert!(write(&dev, 0x29, &[0x00, 0x86, 0x01]));
        dev.advance(2_000_000 + 100_000_000);
        assert_eq!(read16(&dev, 0x29, 0x0089, 1), Some(vec![4]));
    }

    /// The Flow deck's ranger started at 2 ms with a 25 ms period after `setup` (register writes), while
    /// the drone climbs 1 mm per ms and the host sets the range every 1 ms, as `physics.rs` does; every
    /// result read and cleared as it is flagged: (flag time ms, range mm).
    fn climbing_results(setup: &[&[u8]]) -> Vec<(u64, u16)> {
        let dev = DeckSensors::new(Fitted {
            multiranger: false,
            flow: true,
        });
        let range_at = |t_ms: u64| Some(0.5 + t_ms as f32 * 0.001);
        let mut ranges = [None; 6];
        ranges[DOWN] = range_at(2);
        dev.set_ranges(ranges);
        dev.advance(2_000_000);
        for bytes in setup {
            assert!(write(&dev, 0x29, bytes));
        }
        assert!(write(&dev, 0x29, &[0x00, 0x6C, 0, 0, 0x03, 0xE2])); // 25 ms
        assert!(write(&dev, 0x29, &[0x00, 0x87, 0x40])); // first result at 27 ms
        let mut results = Vec::new();
        for t_ms in 3..=80u64 {
            ranges[DOWN] = range_at(t_ms);
            dev.set_ranges(ranges);
            dev.advance(t_ms * 1_000_000);
            if read16(&dev, 0x29, 0x0031, 1) == Some(vec![0x01]) {
                let mm = read16(&dev, 0x29, 0x0096, 2).unwrap();
                results.push((t_ms, u16::from_be_bytes([mm[0], mm[1]])));
                assert!(write(&dev, 0x29, &[0x00, 0x86, 0x01]));
            }
        }
        results
    }

    #[test]
    fn a_result_holds_the_range_from_the_middle_of_its_period() {
        // No budget of the ULD's table in the registers: the whole period is integrated. Flagged at 27, 52
        // and 77 ms, each with the range of 12.5 ms before (taken at the first 1 ms step at or past the
        // middle: 15, 40 and 65 ms).
        assert_eq!(climbing_results(&[]), vec![(27, 515), (52, 540), (77, 565)]);
    }

    #[test]
    fn a_result_holds_the_range_from_half_its_timing_budget_before_the_flag() {
        // The firmware's Flow deck preset: a 20 ms budget in long mode (TIMEOUT_MACROP_A 0x001E, _B 0x0022)
        // in a 25 ms period. Flagged at 27, 52 and 77 ms, each with the range of 10 ms before (17, 42, 67 ms).
        let budget: [&[u8]; 2] = [&[0x00, 0x5E, 0x00, 0x1E], &[0x00, 0x61, 0x00, 0x22]];
        assert_eq!(climbing_results(&budget), vec![(27, 517), (52, 542), (77, 567)]);
    }

    #[test]
    fn an_absent_deck_nacks() {
        let dev = DeckSensors::new(Fitted {
            multiranger: false,
            flow: false,
        });
        dev.advance(5_000_000);
        assert!(!write(&dev, EXPANDER_ADDRESS, &[0x01, 0x00]));
        assert_eq!(read16(&dev, 0x29, 0x00E5, 1), None);
    }
}
