//! `pil.apb8`: the DMA's view of a register block whose rsemu model refuses byte accesses.
//!
//! Job: rsemu 0.0.7's `st.i2c` accepts 16- and 32-bit accesses only and `st.usart` 32-bit only, but
//! embassy-stm32 (like ST's HAL) programs the streams that feed I2C and USART data registers with byte-wide
//! peripheral accesses (`PSIZE` = 8 bit), which the silicon's AHB-to-APB bridge accepts and widens. Mapped in
//! the DMA's address space in place of the peripheral, this object forwards every access to the same address
//! in the CPU's space, widening a narrower access to an aligned 32-bit one: a read returns the addressed byte
//! lane, a write puts the bytes in their lanes and zeroes the others (the data registers take their low bits).
//!
//! For an I2C block it also does what the part's `CR2.LAST` does and rsemu's `st.i2c` keeps as storage
//! (RM0090 §27.6.2: "used in master receiver mode to permit the generation of a NACK on the last received
//! data"): when the receive stream reads the next-to-last byte from DR (its `NDTR`, read without side effects
//! at `rx-ndtr`, still counts that byte and the last, so it reads 2) and LAST is set, ACK is cleared in CR1 so
//! that the last byte is NACKed. Without it the model ACKs one byte too many, and that byte stays in DR with
//! RXNE set, where the next transaction's stream picks it up as its first byte.
//!
//! For the CPU's view of a USART (`usart-cpu = 1`, USART6's CPU-side bridge) it keeps a received byte for the
//! DMA: while `CR3.DMAR` is set, a CPU read of DR returns the value DR holds without taking it or pulling a
//! new byte in (an ordinary read when an error flag is up, so the SR-then-DR clear still works). On the
//! part a receive stream takes the byte a few bus cycles after RXNE sets (RM0090 §10.3.x: the request is served
//! at the next arbitration), so the CPU's DR read in embassy's `check_idle_and_errors` (the IDLE/error clear
//! sequence, run on every ring-buffer read) finds the byte already gone and reads the same value again. In
//! rsemu 0.0.7 the byte waits for the DMA's next scheduling quantum, and a CPU read of SR even pulls the next
//! host byte in at once (`st.usart` `poll_receiver` on every register read): the DR read then took a byte
//! from the DMA's stream, one corrupted syslink frame in about twenty uplinks (docs/pil.md).
//! Keeping only a byte already in DR (RXNE set) was not enough: with RXNE clear the ordinary DR read pulled
//! the next host byte in and consumed it in the same access, about one byte in 12 000.
//! [`USART_RX_KEPT`] counts the reads that found a byte waiting; [`set_usart_cpu_steals`] restores the 0.0.7
//! behaviour for comparison.
//!
//! Non-goals: no timing of its own; apart from the above, no change to what the CPU sees.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use rsemu::core::device::{Device, DeviceClass, PropertySpec, RealizeCtx, ResetKind};
use rsemu::core::error::{BusError, Error, Result};
use rsemu::core::props::{Props, ValueKind};
use rsemu::core::space::{AccessConstraints, AddressSpace, MemAttrs, MemOps, MemResult, Region, RegionRef};
use rsemu::core::value::{Endian, Width};
use rsemu::machine::validate::{ClassSchema, PropSchema};
use rsemu::machine::{BindCtx, Instance};

/// The class name a machine file writes.
pub const CLASS_NAME: &str = "pil.apb8";

/// CPU reads of a USART's DR that left the waiting byte to the receive DMA (see the module doc).
pub static USART_RX_KEPT: AtomicU64 = AtomicU64::new(0);
/// CPU reads of a USART's DR that took a byte the receive DMA was due to take (the 0.0.7 behaviour, when
/// [`set_usart_cpu_steals`] asked for it).
pub static USART_RX_STOLEN: AtomicU64 = AtomicU64::new(0);
static USART_CPU_STEALS: AtomicBool = AtomicBool::new(false);

/// `true`: CPU DR reads take the byte as rsemu 0.0.7 does (to show the stall); `false` (default): the part's
/// behaviour.
pub fn set_usart_cpu_steals(on: bool) {
    USART_CPU_STEALS.store(on, Ordering::Relaxed);
}

/// USART (F4 layout, RM0090 §30.6) offsets and bits.
const USART_SR: u64 = 0x00;
const USART_DR: u64 = 0x04;
const USART_CR3: u64 = 0x14;
const SR_RXNE: u64 = 1 << 5;
/// PE, FE, NF, ORE, IDLE: cleared by the SR-then-DR sequence.
const SR_CLEARED_BY_DR: u64 = 0x1F;
const CR3_DMAR: u64 = 1 << 6;

#[derive(Debug)]
struct Ops {
    base: u64,
    /// This is the CPU's view of a USART: keep a waiting byte for the receive DMA.
    usart_cpu: bool,
    /// The I2C receive stream's NDTR register, for the LAST emulation.
    rx_ndtr: Option<u64>,
    space: OnceLock<Arc<AddressSpace>>,
}

/// I2C v1 offsets and bits (RM0090 §27.6).
const I2C_CR1: u64 = 0x00;
const I2C_CR2: u64 = 0x04;
const I2C_DR: u64 = 0x10;
const CR1_ACK: u64 = 1 << 10;
const CR2_LAST: u64 = 1 << 12;

impl Ops {
    fn emulate_last(&self, space: &AddressSpace, attrs: MemAttrs) -> MemResult {
        let Some(ndtr_at) = self.rx_ndtr else {
            return Ok(());
        };
        let ndtr = space.read(ndtr_at, Width::U32, MemAttrs::DEBUG)? & 0xFFFF;
        let cr2 = space.read(self.base + I2C_CR2, Width::U16, MemAttrs::DEBUG)?;
        if ndtr == 2 && cr2 & CR2_LAST != 0 {
            let cr1 = space.read(self.base + I2C_CR1, Width::U16, MemAttrs::DEBUG)?;
            if cr1 & CR1_ACK != 0 {
                space.write(self.base + I2C_CR1, Width::U16, cr1 & !CR1_ACK, attrs)?;
            }
        }
        Ok(())
    }
}

impl Ops {
    /// A CPU read of a USART's DR that must not take a byte from the receive DMA: true while the DMA
    /// receives and no error flag waits for the SR-then-DR clear, whether or not RXNE is up yet. With RXNE
    /// clear the ordinary read would still take one: `st.usart` pulls the next host byte into DR on any
    /// register read (`poll_receiver`) and the DR read then consumes it, so the byte arrives exactly when the
    /// CPU looks and never reaches the ring (one lost syslink byte in about 12 000). On the part
    /// a DR read with RXNE clear returns the last byte again and the next one arrives on the line's time.
    fn keep_for_dma(&self, space: &AddressSpace) -> MemResult<bool> {
        let sr = space.read(self.base + USART_SR, Width::U32, MemAttrs::DEBUG)?;
        let cr3 = space.read(self.base + USART_CR3, Width::U32, MemAttrs::DEBUG)?;
        let dma_receives = cr3 & CR3_DMAR != 0 && sr & SR_CLEARED_BY_DR == 0;
        let waiting = dma_receives && sr & SR_RXNE != 0;
        if dma_receives && USART_CPU_STEALS.load(Ordering::Relaxed) {
            if waiting {
                USART_RX_STOLEN.fetch_add(1, Ordering::Relaxed);
            }
            return Ok(false);
        }
        if waiting {
            USART_RX_KEPT.fetch_add(1, Ordering::Relaxed);
        }
        Ok(dma_receives)
    }
}

impl MemOps for Ops {
    fn read(&self, offset: u64, dst: &mut [u8], attrs: MemAttrs) -> MemResult {
        let space = self.space.get().ok_or(BusError::BadAccess)?;
        let aligned = offset & !3;
        let lane = (offset & 3) as usize;
        if lane + dst.len() > 4 {
            return Err(BusError::BadAccess);
        }
        if offset == I2C_DR && !attrs.debug && !self.usart_cpu {
            self.emulate_last(space, attrs)?;
        }
        let attrs = if self.usart_cpu && aligned == USART_DR && !attrs.debug && self.keep_for_dma(space)? {
            MemAttrs::DEBUG
        } else {
            attrs
        };
        let word = space.read(self.base + aligned, Width::U32, attrs)? as u32;
        let bytes = word.to_le_bytes();
        dst.copy_from_slice(&bytes[lane..lane + dst.len()]);
        Ok(())
    }

    fn write(&self, offset: u64, src: &[u8], attrs: MemAttrs) -> MemResult {
        let space = self.space.get().ok_or(BusError::BadAccess)?;
        let aligned = offset & !3;
        let lane = (offset & 3) as usize;
        if lane + src.len() > 4 {
            return Err(BusError::BadAccess);
        }
        let mut bytes = [0u8; 4];
        bytes[lane..lane + src.len()].copy_from_slice(src);
        space.write(
            self.base + aligned,
            Width::U32,
            u64::from(u32::from_le_bytes(bytes)),
            attrs,
        )
    }

    fn constraints(&self) -> AccessConstraints {
        AccessConstraints::ANY
            .with_widths(Width::U8, Width::U32)
            .with_endian(Endian::Little)
    }
}

/// One bridged register block.
#[derive(Debug)]
pub struct Apb8 {
    ops: Arc<Ops>,
    region: RegionRef,
}

impl Apb8 {
    /// From the machine file: `base` (the block's address in the CPU's space) and `size`.
    pub fn new(props: &Props) -> Result<Self> {
        let bad = |m: &str| Error::Config {
            at: String::from(CLASS_NAME),
            message: String::from(m),
        };
        let base = props
            .require("base")?
            .as_uint()
            .ok_or_else(|| bad("`base` must be an address"))?;
        let size = props
            .require("size")?
            .as_uint()
            .ok_or_else(|| bad("`size` must be a byte count"))?;
        let rx_ndtr = match props.get("rx-ndtr") {
            Some(v) => Some(v.as_uint().ok_or_else(|| bad("`rx-ndtr` must be an address"))?),
            None => None,
        };
        let usart_cpu = match props.get("usart-cpu") {
            Some(v) => v.as_uint().ok_or_else(|| bad("`usart-cpu` must be 0 or 1"))? != 0,
            None => false,
        };
        let ops = Arc::new(Ops {
            base,
            usart_cpu,
            rx_ndtr,
            space: OnceLock::new(),
        });
        let region = Arc::new(Region::io("apb8", size, Arc::clone(&ops) as Arc<dyn MemOps>));
        Ok(Self { ops, region })
    }
}

impl Device for Apb8 {
    fn class(&self) -> &'static DeviceClass {
        &CLASS
    }

    fn realize(&self, _ctx: &mut RealizeCtx<'_>) -> Result<()> {
        Ok(())
    }

    fn reset(&self, _kind: ResetKind) {}

    fn region(&self, name: &str) -> Option<RegionRef> {
        matches!(name, "" | "regs").then(|| Arc::clone(&self.region))
    }
}

impl Instance for Apb8 {
    fn bind(&self, ctx: &BindCtx<'_>) -> Result<()> {
        let space = ctx.space().ok_or_else(|| Error::Config {
            at: String::from(CLASS_NAME),
            message: String::from("the bridge forwards into the CPU's space: add `space = mem`"),
        })?;
        let _ = self.ops.space.set(Arc::clone(space));
        Ok(())
    }
}

/// The `pil.apb8` device class.
pub static CLASS: DeviceClass = DeviceClass {
    name: CLASS_NAME,
    version: 1,
    summary: "forwards DMA accesses to a register block, widening byte accesses (cfnav PIL)",
    properties: &[
        PropertySpec {
            name: "base",
            kind: ValueKind::Uint,
            required: true,
            summary: "the block's address in the CPU's space",
        },
        PropertySpec {
            name: "size",
            kind: ValueKind::Uint,
            required: true,
            summary: "the block's size in bytes",
        },
        PropertySpec {
            name: "rx-ndtr",
            kind: ValueKind::Uint,
            required: false,
            summary: "I2C only: the receive stream's NDTR address, to emulate CR2.LAST",
        },
        PropertySpec {
            name: "usart-cpu",
            kind: ValueKind::Uint,
            required: false,
            summary: "1: the CPU's view of a USART; a DR read leaves a byte the receive DMA is due to take",
        },
    ],
    construct: |props| Ok(Box::new(Apb8::new(props)?)),
};

/// What the validator should know about `pil.apb8`.
pub fn schema() -> ClassSchema {
    ClassSchema::new(CLASS_NAME)
        .prop(PropSchema::new("base", ValueKind::Uint))
        .prop(PropSchema::new("size", ValueKind::Uint))
        .prop(PropSchema::new("rx-ndtr", ValueKind::Uint))
        .prop(PropSchema::new("usart-cpu", ValueKind::Uint))
        .region("")
        .region("regs")
}
