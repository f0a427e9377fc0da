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
//! Non-goals: no timing of its own, no change to what the CPU sees (its space maps the peripheral directly).

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

#[derive(Debug)]
struct Ops {
    base: u64,
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

impl MemOps for Ops {
    fn read(&self, offset: u64, dst: &mut [u8], attrs: MemAttrs) -> MemResult {
        let space = self.space.get().ok_or(BusError::BadAccess)?;
        let aligned = offset & !3;
        let lane = (offset & 3) as usize;
        if lane + dst.len() > 4 {
            return Err(BusError::BadAccess);
        }
        if offset == I2C_DR && !attrs.debug {
            self.emulate_last(space, attrs)?;
        }
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
        let ops = Arc::new(Ops {
            base,
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
    ],
    construct: |props| Ok(Box::new(Apb8::new(props)?)),
};

/// What the validator should know about `pil.apb8`.
pub fn schema() -> ClassSchema {
    ClassSchema::new(CLASS_NAME)
        .prop(PropSchema::new("base", ValueKind::Uint))
        .prop(PropSchema::new("size", ValueKind::Uint))
        .prop(PropSchema::new("rx-ndtr", ValueKind::Uint))
        .region("")
        .region("regs")
}
