//! The emulated Crazyflie 2.1: the flash image from the firmware ELF, the machine (rsemu's Cortex-M4F and
//! STM32F4 models, `crazyflie21.machine`), the device models on its buses and the host's views of it (GPIO
//! output registers, FLASH_ACR, RCC_CSR, the RTT up-buffer, the syslink byte stream).
//!
//! Job: everything that touches rsemu's API, so the rest of the tool is plain Rust.
//!
//! Non-goals: no physics (that is `physics.rs`), no bootloader: the first 16 KiB of flash hold a two-word vector
//! table (the application's initial SP and reset vector), which is what the Crazyflie bootloader hands over
//! (docs/hardware.md §1: it loads MSP from 0x08004000 and jumps to its reset vector; the image sets VTOR
//! itself, cortex-m-rt `set-vtor`). The application bytes are the ELF's LOAD segments, unmodified.

use std::sync::Arc;

use anyhow::{Context, Result, anyhow, bail};
use object::{Object, ObjectSegment, ObjectSymbol};
use rsemu::bus::i2c::buses;
use rsemu::core::clock::GlobalTime;
use rsemu::core::space::{AddressSpace, MemAttrs};
use rsemu::core::value::Width;
use rsemu::host::chardev::{CharPort, ports};
use rsemu::machine::{Machine, catalog};

use crate::deck::{DeckSensors, Fitted};
use crate::devices::{Bmi088, Eeprom, Faults, default_config_block};
use crate::flow::{self, CsTarget, Pmw3901};
use crate::pin::{self, PinHandle};
use crate::stuck::{self, StuckLine};
use crate::{apb8, dreq};

/// The machine description (derived from rsemu's STM32F407 board).
pub const MACHINE_TEXT: &str = include_str!("../crazyflie21.machine");

/// Flash base and size (STM32F405RG: 1 MiB).
pub const FLASH_BASE: u64 = 0x0800_0000;
pub const FLASH_SIZE: usize = 1 << 20;
/// Where the application starts (after the bootloader's 16 KiB).
pub const APP_BASE: u64 = 0x0800_4000;

/// RM0090 §3.9.1: FLASH_ACR, LATENCY[3:0], PRFTEN bit 8, ICEN bit 9, DCEN bit 10.
pub const FLASH_ACR: u64 = 0x4002_3C00;
/// RM0090 §7.3.21: RCC_CSR, IWDGRSTF bit 29.
pub const RCC_CSR: u64 = 0x4002_3874;
/// GPIOx_ODR (RM0090 §8.4.6): port C at 0x40020800, port D at 0x40020C00, ODR at +0x14.
pub const GPIOC_ODR: u64 = 0x4002_0814;
pub const GPIOD_ODR: u64 = 0x4002_0C14;

/// The flash image and what the host needs from the ELF.
pub struct Image {
    pub flash: Vec<u8>,
    pub rtt_address: Option<u64>,
    /// Named statics of the image the report reads (deck flags, ...): (substring of the symbol, address).
    pub statics: Vec<(&'static str, u64)>,
}

/// The image's statics the report reads, by a substring of their (mangled) symbol names: the deck flags
/// behind the `deck.bcMultiranger` / `deck.bcFlow2` parameters (`src/board/mod.rs`).
pub const STATICS: [&str; 2] = ["DECK_MULTIRANGER", "DECK_FLOW2"];

/// Builds the 1 MiB flash image from the ELF's LOAD segments (erased bytes are 0xFF) and the two-word vector
/// table at the flash base.
pub fn load_image(elf: &[u8]) -> Result<Image> {
    let file = object::File::parse(elf).context("the firmware is not an ELF file")?;
    let mut flash = vec![0xFF; FLASH_SIZE];
    let mut app_bytes = 0;
    for segment in file.segments() {
        let data = segment.data().context("reading a segment")?;
        if data.is_empty() {
            continue;
        }
        // The load (physical) address: .data's initial values are stored in flash after .rodata.
        let (offset, _) = segment.file_range();
        let lma = physical_address(elf, offset).unwrap_or(segment.address());
        if lma < FLASH_BASE || lma + data.len() as u64 > FLASH_BASE + FLASH_SIZE as u64 {
            continue;
        }
        if lma < APP_BASE {
            bail!("a LOAD segment at {lma:#x} lies in the bootloader's sector");
        }
        let at = (lma - FLASH_BASE) as usize;
        flash[at..at + data.len()].copy_from_slice(data);
        app_bytes += data.len();
    }
    if app_bytes == 0 {
        bail!("no LOAD segment in flash: is this the thumbv7em firmware ELF?");
    }
    let app = (APP_BASE - FLASH_BASE) as usize;
    let sp_and_reset: [u8; 8] = flash[app..app + 8].try_into().context("vector table")?;
    flash[..8].copy_from_slice(&sp_and_reset);
    let rtt_address = file
        .symbols()
        .find(|s| s.name() == Ok("_SEGGER_RTT"))
        .map(|s| s.address());
    let statics = STATICS
        .iter()
        .filter_map(|&name| {
            file.symbols()
                .find(|s| s.name().is_ok_and(|n| n.contains(name)))
                .map(|s| (name, s.address()))
        })
        .collect();
    Ok(Image {
        flash,
        rtt_address,
        statics,
    })
}

/// The physical address of the program header whose file range starts at `offset` (ELF32 little-endian;
/// `object`'s segment API gives only the virtual address).
fn physical_address(elf: &[u8], offset: u64) -> Option<u64> {
    let u32_at = |at: usize| {
        elf.get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let u16_at = |at: usize| elf.get(at..at + 2).map(|b| u16::from_le_bytes([b[0], b[1]]));
    if elf.get(4) != Some(&1) {
        return None; // not ELF32
    }
    let phoff = u32_at(0x1C)? as usize;
    let phentsize = u16_at(0x2A)? as usize;
    let phnum = u16_at(0x2C)? as usize;
    (0..phnum).find_map(|i| {
        let ph = phoff + i * phentsize;
        let p_type = u32_at(ph)?;
        let p_offset = u32_at(ph + 4)?;
        let p_paddr = u32_at(ph + 12)?;
        (p_type == 1 && u64::from(p_offset) == offset).then_some(u64::from(p_paddr))
    })
}

/// The running board.
pub struct Board {
    pub machine: Machine,
    pub syslink: Arc<CharPort>,
    pub imu: Arc<Bmi088>,
    /// The gyroscope's data-ready line (PC14).
    pub imu_int3: PinHandle,
    /// The nRF51's RTS (flow control) into PA4: low (send) unless `--fault rts-high`.
    pub nrf_rts: PinHandle,
    /// The Multi-ranger and the Flow deck's height ranger on I2C1.
    pub deck: Arc<DeckSensors>,
    /// The Flow deck's PMW3901 on SPI1.
    pub flow: Arc<Pmw3901>,
    /// SDA of I2C3 and of I2C1, held low by a stuck slave when a fault asks for it (`crate::stuck`).
    pub sensors_sda: StuckLine,
    pub deck_sda: StuckLine,
    mem: Arc<AddressSpace>,
}

/// The scheduler's quantum, ns: the longest the DMA controllers wait between two turns.
///
/// rsemu's `st.dma` moves its beats only when the scheduler gives it a turn (`Device::run`, once a round),
/// and with the default 1 ms quantum a round lasts until the next event anywhere on the board. SPI1 shifts a
/// byte every 6.1 µs (1.3125 MHz): when no other event ended a round within two byte times of a received
/// byte, the next byte landed on the unread one (SR.OVR, RM0090 §28.3.10), the RX stream waited for a byte
/// that never came and the flow read timed out (bench boot, 3 s: 32 timeouts with 1 ms, 16 with 20 µs,
/// none with 5, 4 or 2 µs). On the part a request is served within a few AHB cycles, so this was the
/// emulator's, not the firmware's. Every round costs scheduler time whether anything happens or not (about
/// half of the emulator's time once a sleeping core skips its idle cycles), but 4 µs, which still served
/// every SPI byte, made cflib's connect stall in `--client toc` (request 68 of 237 never reached the image:
/// a quantum-dependent path in the nRF51 model or USART6 not yet understood, docs/pil.md "Speed"), so the
/// quantum stays at 2 µs, a third of a byte time.
pub const QUANTUM_NS: u64 = 2_000;

impl Board {
    /// Builds the machine around `flash` with the device models and faults.
    pub fn new(flash: Vec<u8>, faults: Faults, fitted: Fitted) -> Result<Self> {
        let mut registry = catalog::registry().map_err(|e| anyhow!("rsemu registry: {e}"))?;
        registry
            .add(&dreq::CLASS)
            .map_err(|e| anyhow!("registering pil.dreq: {e}"))?;
        registry
            .add(&apb8::CLASS)
            .map_err(|e| anyhow!("registering pil.apb8: {e}"))?;
        registry
            .add(&pin::CLASS)
            .map_err(|e| anyhow!("registering pil.pin: {e}"))?;
        registry
            .add(&flow::CS_CLASS)
            .map_err(|e| anyhow!("registering pil.cs: {e}"))?;
        registry
            .add(&stuck::CLASS)
            .map_err(|e| anyhow!("registering pil.stuck: {e}"))?;
        let mut options = catalog::build_options().map_err(|e| anyhow!("rsemu build options: {e}"))?;
        options.classes.insert(dreq::schema());
        options.classes.insert(apb8::schema());
        options.classes.insert(pin::schema());
        options.classes.insert(flow::cs_schema());
        options.classes.insert(stuck::schema());
        let sensors_sda = StuckLine::new(faults.sensor_bus_stuck);
        let deck_sda = StuckLine::new(faults.deck_bus_stuck);
        let (s_line, d_line) = (sensors_sda.clone(), deck_sda.clone());
        options
            .bindings
            .bind(stuck::CLASS_NAME, move |props| {
                let line = match stuck::bus_name(props)?.as_str() {
                    "sensors" => s_line.clone(),
                    _ => d_line.clone(),
                };
                Ok(Arc::new(stuck::Stuck::new(line)))
            })
            .map_err(|e| anyhow!("binding pil.stuck: {e}"))?;
        options.realize.scheduler.quantum = rsemu::core::clock::GlobalTime::from_nanos(QUANTUM_NS);
        let cs_target = CsTarget::default();
        let cs_handle = cs_target.clone();
        options
            .bindings
            .bind(flow::CS_CLASS_NAME, move |_props| {
                Ok(Arc::new(flow::Cs::new(cs_handle.clone())))
            })
            .map_err(|e| anyhow!("binding pil.cs: {e}"))?;
        let imu_int3 = PinHandle::default();
        let nrf_rts = PinHandle::default();
        let (int3_handle, rts_handle) = (imu_int3.clone(), nrf_rts.clone());
        options
            .bindings
            .bind(pin::CLASS_NAME, move |props| {
                let handle = if pin::is_nrf_rts(props) {
                    rts_handle.clone()
                } else {
                    int3_handle.clone()
                };
                Ok(Arc::new(pin::Pin::new(handle)))
            })
            .map_err(|e| anyhow!("binding pil.pin: {e}"))?;
        options
            .bindings
            .bind(apb8::CLASS_NAME, |props| Ok(Arc::new(apb8::Apb8::new(props)?)))
            .map_err(|e| anyhow!("binding pil.apb8: {e}"))?;
        let tx_dead = faults.syslink_tx_dead;
        options
            .bindings
            .bind(dreq::CLASS_NAME, move |props| {
                let line = dreq::Dreq::new(props)?;
                Ok(Arc::new(if tx_dead && dreq::Dreq::is_usart_tx(props) {
                    line.dead()
                } else {
                    line
                }))
            })
            .map_err(|e| anyhow!("binding pil.dreq: {e}"))?;
        let hosts = Arc::clone(&options.realize.hosts);
        let imu = Arc::new(Bmi088::new(faults));
        let sensors = buses::open(&hosts, "sensors").map_err(|e| anyhow!("I2C3 bus: {e}"))?;
        sensors
            .attach(Arc::clone(&imu) as _)
            .map_err(|e| anyhow!("attaching the BMI088: {e}"))?;
        sensors_sda.hold_bus(&sensors)?;
        let deck = buses::open(&hosts, "deck").map_err(|e| anyhow!("I2C1 bus: {e}"))?;
        deck.attach(Arc::new(Eeprom::new(&default_config_block())))
            .map_err(|e| anyhow!("attaching the EEPROM: {e}"))?;
        let deck_sensors = Arc::new(DeckSensors::new(fitted));
        deck.attach(Arc::clone(&deck_sensors) as _)
            .map_err(|e| anyhow!("attaching the deck rangers: {e}"))?;
        deck_sda.hold_bus(&deck)?;
        let spi = rsemu::bus::spi::buses::open(&hosts, "flowdeck").map_err(|e| anyhow!("SPI1 bus: {e}"))?;
        let pmw = Arc::new(Pmw3901::new(fitted.flow));
        spi.attach(rsemu::bus::spi::ChipSelect(0), Arc::clone(&pmw) as _)
            .map_err(|e| anyhow!("attaching the PMW3901: {e}"))?;
        cs_target.set(spi);
        let syslink = ports::open(&hosts, "syslink").map_err(|e| anyhow!("USART6 port: {e}"))?;
        options.realize.media.insert("firmware", flash);
        let machine = rsemu::machine::build("crazyflie21", MACHINE_TEXT, &registry, &options)
            .map_err(|e| anyhow!("the machine does not build: {e}"))?;
        let mem = Arc::clone(
            machine
                .space("mem")
                .ok_or_else(|| anyhow!("the machine has no `mem` space"))?,
        );
        Ok(Self {
            machine,
            syslink,
            imu,
            imu_int3,
            nrf_rts,
            deck: deck_sensors,
            flow: pmw,
            sensors_sda,
            deck_sda,
            mem,
        })
    }

    /// Runs `ns` nanoseconds of virtual time.
    pub fn run_ns(&mut self, ns: u64) -> Result<()> {
        self.machine
            .run_for(GlobalTime::from_nanos(ns))
            .map_err(|e| anyhow!("the emulator stopped: {e}"))
    }

    /// Virtual time since power-on, in ns.
    pub fn now_ns(&self) -> u64 {
        self.machine.now().as_nanos()
    }

    /// A side-effect-free 32-bit read.
    pub fn peek32(&self, addr: u64) -> Option<u32> {
        self.mem.read(addr, Width::U32, MemAttrs::DEBUG).ok().map(|v| v as u32)
    }

    /// A side-effect-free byte read.
    pub fn peek8(&self, addr: u64) -> Option<u8> {
        self.mem.read(addr, Width::U8, MemAttrs::DEBUG).ok().map(|v| v as u8)
    }

    /// A host write into RAM (the RTT read pointer).
    pub fn poke32(&self, addr: u64, value: u32) -> bool {
        self.mem
            .write(addr, Width::U32, u64::from(value), MemAttrs::DEBUG)
            .is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stuck::Release;

    /// A guest-style (not debug) 32-bit write, as the firmware's STR would make.
    fn write32(board: &Board, addr: u64, value: u32) {
        board
            .mem
            .write(addr, Width::U32, u64::from(value), MemAttrs::DEFAULT)
            .expect("write");
    }

    /// A guest-style (not debug) 32-bit read, as the firmware's LDR would make.
    fn read32(board: &Board, addr: u64) -> u32 {
        board.mem.read(addr, Width::U32, MemAttrs::DEFAULT).expect("read") as u32
    }

    /// embassy's ring-buffered reader reads SR then DR on every call (`check_idle_and_errors`) while the DMA
    /// receives. A byte the nRF sends between the two must still reach the DMA when the DR read comes:
    /// `st.usart` latches a waiting host byte on any register access, and the bridge once let the CPU's read
    /// consume it there (one syslink byte in about 12 000 never reached the ring, docs/pil.md).
    #[test]
    fn a_cpu_read_of_usart6_dr_leaves_the_next_byte_to_the_receive_dma() {
        const USART6: u64 = 0x4001_1400;
        // The DMA's view of USART6 (`usart6-alias` in crazyflie21.machine): `st.usart` itself.
        const USART6_DMA_VIEW: u64 = 0x4fff_0000;
        let fitted = Fitted {
            multiranger: false,
            flow: false,
        };
        let board = Board::new(vec![0xFF; FLASH_SIZE], Faults::default(), fitted).expect("machine");
        write32(&board, 0x4002_3844, 1 << 5); // RCC_APB2ENR.USART6EN (RM0090 §7.3.14)
        write32(&board, USART6 + 0x0C, (1 << 13) | (1 << 2)); // CR1: UE, RE
        write32(&board, USART6 + 0x14, 1 << 6); // CR3: DMAR
        assert_eq!(
            board.peek32(USART6).unwrap() & 0x20,
            0,
            "RXNE clear: nothing received yet"
        );
        // The sequence's SR read finds nothing; the byte comes off the line before its DR read.
        let _ = read32(&board, USART6);
        assert_eq!(board.syslink.feed(&[0xBC]), 1);
        let _ = read32(&board, USART6 + 0x04);
        let sr = board
            .mem
            .read(USART6_DMA_VIEW, Width::U32, MemAttrs::DEFAULT)
            .expect("SR") as u32;
        assert_ne!(sr & 0x20, 0, "the byte is waiting for the DMA (RXNE)");
        let dr = board
            .mem
            .read(USART6_DMA_VIEW + 0x04, Width::U32, MemAttrs::DEFAULT)
            .expect("DR") as u32;
        assert_eq!(dr & 0xFF, 0xBC, "the DMA's read takes the byte the nRF sent");
        assert_eq!(board.peek32(USART6).unwrap() & 0x20, 0, "and RXNE clears with it");
    }

    /// What the firmware's recovery does (`src/board/sensors.rs` `I2cRecoveryPins`), by register, on the
    /// machine's own GPIO model: SCL PA8 and SDA PC9 as open-drain outputs, released; reading IDR shows
    /// the stuck slave; each BSRR reset/set of PA8 is one SCL clock.
    #[test]
    fn the_machines_i2c3_pins_see_the_stuck_slave_and_its_release_after_k_clocks() {
        const GPIOA: u64 = 0x4002_0000;
        const GPIOC: u64 = 0x4002_0800;
        const I2C3_SR2: u64 = 0x4000_5C18;
        let faults = Faults {
            sensor_bus_stuck: Some(Release::AfterClocks(3)),
            ..Faults::default()
        };
        let fitted = Fitted {
            multiranger: false,
            flow: false,
        };
        let board = Board::new(vec![0xFF; FLASH_SIZE], faults, fitted).expect("machine");
        // RCC_AHB1ENR: GPIOA, GPIOC (RM0090 §7.3.10); RCC_APB1ENR: I2C3EN bit 23 (§7.3.13).
        write32(&board, 0x4002_3830, 0b101);
        write32(&board, 0x4002_3840, 1 << 23);
        assert_ne!(board.peek32(I2C3_SR2).unwrap() & 0b10, 0, "SR2.BUSY while SDA is held");
        for (port, pin) in [(GPIOA, 8u32), (GPIOC, 9)] {
            write32(&board, port + 0x18, 1 << pin); // BSRR: released before the mode switch
            write32(&board, port + 0x04, 1 << pin); // OTYPER: open-drain
            let moder = board.peek32(port).unwrap() & !(0b11 << (2 * pin));
            write32(&board, port, moder | (0b01 << (2 * pin))); // MODER: output
        }
        let sda_high = || board.peek32(GPIOC + 0x10).unwrap() & (1 << 9) != 0;
        assert!(!sda_high(), "IDR reads the slave holding SDA low although ODR is 1");
        for clock in 1..=3 {
            assert!(!sda_high(), "still held before clock {clock}");
            write32(&board, GPIOA + 0x18, 1 << (8 + 16)); // SCL low
            write32(&board, GPIOA + 0x18, 1 << 8); // SCL high
        }
        assert!(sda_high(), "released after the third clock");
        let stats = board.sensors_sda.stats();
        assert_eq!((stats.clocks_seen, stats.holding), (3, false));
        assert_eq!(
            board.deck_sda.stats().clocks_seen,
            0,
            "the deck bus's line is another net"
        );
    }
}
