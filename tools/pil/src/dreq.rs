//! `pil.dreq`: the DMA request line of one peripheral direction, for the rsemu STM32 models that have none.
//!
//! Job: rsemu 0.0.7's `st.i2c` (I2C v1) and `st.usart` keep their DMA enable bits as plain storage, and
//! `stm32.spi` drives no request line, so a stream armed for them would wait forever (embassy's I2C, USART and
//! SPI drivers all move their data by DMA). One `pil.dreq` object stands for one request line: wired to the
//! stream and channel of RM0090 Table 42/43, it publishes a [`DmaPeripheral`] whose `dma_ready` the stream
//! polls as the request level. The level is computed from the peripheral's own registers, read without side
//! effects (`MemAttrs::DEBUG`): the direction's DMA enable bit and TXE (transmit) or RXNE (receive). The
//! stream then accesses the data register over the bus, which clears the flag, exactly as on the part.
//!
//! Non-goals: no data path (the stream moves the bytes), no flow control by the peripheral (`PFCTRL`), no
//! I2C `LAST` handling (the model ACKs one extra byte on a DMA read; the master's STOP ends it).
//!
//! Registers (RM0090): I2C `CR2.DMAEN` bit 11 at +0x04, `SR1.TXE` bit 7 / `SR1.RXNE` bit 6 at +0x14 (§27.6);
//! USART `SR.TXE` bit 7 / `SR.RXNE` bit 5 at +0x00, `CR3.DMAT` bit 7 / `CR3.DMAR` bit 6 at +0x14 (§30.6);
//! SPI `CR2.TXDMAEN` bit 1 / `RXDMAEN` bit 0 at +0x04, `SR.TXE` bit 1 / `SR.RXNE` bit 0 at +0x08 (§28.5).

use std::sync::{Arc, OnceLock};

use rsemu::core::device::{Device, DeviceClass, PropertySpec, RealizeCtx, ResetKind};
use rsemu::core::error::{Error, Result};
use rsemu::core::props::{Props, ValueKind};
use rsemu::core::space::{AddressSpace, MemAttrs};
use rsemu::core::value::Width;
use rsemu::core::wire::{DmaPeripheral, WireSource};
use rsemu::machine::validate::{ClassSchema, PortDir, PropSchema};
use rsemu::machine::{BindCtx, Instance};

/// The class name a machine file writes.
pub const CLASS_NAME: &str = "pil.dreq";

/// Which peripheral family's registers decide the level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    I2c,
    Usart,
    Spi,
}

/// Where the enable bit and the status flag are, for one family and direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RequestRule {
    /// Offset of the register holding the DMA enable bit.
    pub enable_off: u64,
    /// The DMA enable bit.
    pub enable_mask: u32,
    /// Offset of the status register.
    pub status_off: u64,
    /// TXE (transmit) or RXNE (receive).
    pub status_mask: u32,
}

impl RequestRule {
    /// The rule for `kind` in direction `tx` (true) or receive (false).
    pub fn new(kind: Kind, tx: bool) -> Self {
        let (enable_off, status_off, enable_mask, status_mask) = match (kind, tx) {
            (Kind::I2c, true) => (0x04, 0x14, 1 << 11, 1 << 7),
            (Kind::I2c, false) => (0x04, 0x14, 1 << 11, 1 << 6),
            (Kind::Usart, true) => (0x14, 0x00, 1 << 7, 1 << 7),
            (Kind::Usart, false) => (0x14, 0x00, 1 << 6, 1 << 5),
            (Kind::Spi, true) => (0x04, 0x08, 1 << 1, 1 << 1),
            (Kind::Spi, false) => (0x04, 0x08, 1 << 0, 1 << 0),
        };
        Self {
            enable_off,
            enable_mask,
            status_off,
            status_mask,
        }
    }

    /// The request level for these two register values.
    pub fn level(&self, enable_reg: u32, status_reg: u32) -> bool {
        enable_reg & self.enable_mask != 0 && status_reg & self.status_mask != 0
    }
}

/// The polled half: the space to read through and the rule.
#[derive(Debug)]
struct Peer {
    base: u64,
    rule: RequestRule,
    space: OnceLock<Arc<AddressSpace>>,
    /// The line never rises (a fault: a stream armed on it never moves a byte).
    dead: bool,
}

impl Peer {
    fn read(&self, off: u64) -> Option<u32> {
        let space = self.space.get()?;
        // A 32-bit access: the one width all three models accept (rsemu's USART takes words only).
        space
            .read(self.base + off, Width::U32, MemAttrs::DEBUG)
            .ok()
            .map(|v| v as u32)
    }
}

impl DmaPeripheral for Peer {
    fn dma_read(&self, _terminal: bool) -> u8 {
        // Not used by `st.dma`: the data goes over the bus at PAR.
        0
    }

    fn dma_write(&self, _byte: u8, _terminal: bool) {}

    fn dma_ready(&self) -> bool {
        if self.dead {
            return false;
        }
        match (self.read(self.rule.enable_off), self.read(self.rule.status_off)) {
            (Some(enable), Some(status)) => self.rule.level(enable, status),
            _ => false,
        }
    }
}

/// One request line.
#[derive(Debug)]
pub struct Dreq {
    peer: Arc<Peer>,
}

fn config_error(message: &str) -> Error {
    Error::Config {
        at: String::from(CLASS_NAME),
        message: String::from(message),
    }
}

impl Dreq {
    /// From the machine file's properties: `base` (address), `kind` ("i2c", "usart", "spi"), `dir` ("tx",
    /// "rx").
    pub fn new(props: &Props) -> Result<Self> {
        let base = props
            .require("base")?
            .as_uint()
            .ok_or_else(|| config_error("`base` must be an address"))?;
        let kind = match props.require("kind")?.as_str() {
            Some("i2c") => Kind::I2c,
            Some("usart") => Kind::Usart,
            Some("spi") => Kind::Spi,
            _ => return Err(config_error("`kind` must be \"i2c\", \"usart\" or \"spi\"")),
        };
        let tx = match props.require("dir")?.as_str() {
            Some("tx") => true,
            Some("rx") => false,
            _ => return Err(config_error("`dir` must be \"tx\" or \"rx\"")),
        };
        Ok(Self {
            peer: Arc::new(Peer {
                base,
                rule: RequestRule::new(kind, tx),
                space: OnceLock::new(),
                dead: false,
            }),
        })
    }

    /// Whether the machine file's properties name a USART transmit line (the one `--fault syslink-tx-dead`
    /// kills: the board has one USART, USART6).
    pub fn is_usart_tx(props: &Props) -> bool {
        props.get("kind").and_then(|v| v.as_str()) == Some("usart")
            && props.get("dir").and_then(|v| v.as_str()) == Some("tx")
    }

    /// The same line, never raised.
    pub fn dead(self) -> Self {
        let peer = Peer {
            base: self.peer.base,
            rule: self.peer.rule,
            space: OnceLock::new(),
            dead: true,
        };
        Self { peer: Arc::new(peer) }
    }
}

impl Device for Dreq {
    fn class(&self) -> &'static DeviceClass {
        &CLASS
    }

    fn realize(&self, _ctx: &mut RealizeCtx<'_>) -> Result<()> {
        Ok(())
    }

    fn reset(&self, _kind: ResetKind) {}

    fn connect(&self, port: &str, _source: WireSource) -> Result<()> {
        // The line is never driven: the stream polls `dma_ready` instead (see the module documentation).
        if port == "req" {
            Ok(())
        } else {
            Err(config_error("the only pin is `req`"))
        }
    }

    fn dma_peripheral(&self, port: &str) -> Option<Arc<dyn DmaPeripheral>> {
        (port == "req").then(|| Arc::clone(&self.peer) as Arc<dyn DmaPeripheral>)
    }
}

impl Instance for Dreq {
    fn bind(&self, ctx: &BindCtx<'_>) -> Result<()> {
        let space = ctx
            .space()
            .ok_or_else(|| config_error("a request line reads its peripheral's registers: add `space = mem`"))?;
        let _ = self.peer.space.set(Arc::clone(space));
        Ok(())
    }
}

/// The `pil.dreq` device class.
pub static CLASS: DeviceClass = DeviceClass {
    name: CLASS_NAME,
    version: 1,
    summary: "a DMA request line computed from a peripheral's enable bit and TXE/RXNE (cfnav PIL)",
    properties: &[
        PropertySpec {
            name: "base",
            kind: ValueKind::Uint,
            required: true,
            summary: "the peripheral's register base",
        },
        PropertySpec {
            name: "kind",
            kind: ValueKind::Str,
            required: true,
            summary: "\"i2c\", \"usart\" or \"spi\"",
        },
        PropertySpec {
            name: "dir",
            kind: ValueKind::Str,
            required: true,
            summary: "\"tx\" or \"rx\"",
        },
    ],
    construct: |props| Ok(Box::new(Dreq::new(props)?)),
};

/// What the validator should know about `pil.dreq`.
pub fn schema() -> ClassSchema {
    ClassSchema::new(CLASS_NAME)
        .prop(PropSchema::new("base", ValueKind::Uint))
        .prop(PropSchema::new("kind", ValueKind::Str).values(&["i2c", "usart", "spi"]))
        .prop(PropSchema::new("dir", ValueKind::Str).values(&["tx", "rx"]))
        .port("req", PortDir::Out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_needs_both_the_enable_bit_and_the_flag() {
        // I2C: CR2.DMAEN (bit 11), SR1.TXE (bit 7) / RXNE (bit 6), RM0090 §27.6.
        let tx = RequestRule::new(Kind::I2c, true);
        assert!(tx.level(1 << 11, 1 << 7));
        assert!(!tx.level(0, 1 << 7), "DMAEN clear");
        assert!(!tx.level(1 << 11, 1 << 6), "RXNE is not a transmit request");
        let rx = RequestRule::new(Kind::I2c, false);
        assert!(rx.level(1 << 11, 1 << 6) && !rx.level(1 << 11, 1 << 7));
        // USART: CR3.DMAT (bit 7) / DMAR (bit 6), SR.TXE (bit 7) / RXNE (bit 5), §30.6.
        let utx = RequestRule::new(Kind::Usart, true);
        let urx = RequestRule::new(Kind::Usart, false);
        assert_eq!((utx.enable_off, utx.status_off), (0x14, 0x00));
        assert!(utx.level(1 << 7, 1 << 7) && !utx.level(1 << 6, 1 << 7));
        assert!(urx.level(1 << 6, 1 << 5) && !urx.level(1 << 6, 1 << 7));
        // SPI: CR2.TXDMAEN (bit 1) / RXDMAEN (bit 0), SR.TXE (bit 1) / RXNE (bit 0), §28.5.
        let stx = RequestRule::new(Kind::Spi, true);
        let srx = RequestRule::new(Kind::Spi, false);
        assert!(stx.level(0b10, 0b10) && !stx.level(0b01, 0b10));
        assert!(srx.level(0b01, 0b01) && !srx.level(0b01, 0b10));
    }
}
