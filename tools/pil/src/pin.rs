//! `pil.pin`: one output line the host drives (the BMI088's INT3 data-ready line into PC14; the nRF51's RTS
//! into PA4). `net` names which (`"imu-int3"`, the default, or `"nrf-rts"`), so the host gets one handle each.
//!
//! Job: give the host a [`WireSource`] on a net of the machine, so a device model that lives outside rsemu
//! (an [`rsemu::bus::i2c::I2cSlave`] has no pins) can still raise a GPIO/EXTI edge. The host sets the level
//! between run slices, so an edge lands on a slice boundary (the tool uses 1 µs-exact boundaries it chooses).
//!
//! Non-goals: no drive strength, no reading back.

use std::sync::{Arc, Mutex};

use rsemu::core::device::PropertySpec;
use rsemu::core::device::{Device, DeviceClass, RealizeCtx, ResetKind};
use rsemu::core::error::{Error, Result};
use rsemu::core::props::{Props, ValueKind};
use rsemu::core::wire::{Level, WireSource};
use rsemu::machine::Instance;
use rsemu::machine::validate::{ClassSchema, PortDir, PropSchema};

/// The class name a machine file writes.
pub const CLASS_NAME: &str = "pil.pin";

/// The host's end: set the level of the line.
#[derive(Debug, Clone, Default)]
pub struct PinHandle(Arc<Mutex<Option<WireSource>>>);

impl PinHandle {
    /// Drives the line; false if the machine did not wire it.
    pub fn set(&self, high: bool) -> bool {
        let guard = self.0.lock().unwrap_or_else(|e| e.into_inner());
        guard
            .as_ref()
            .is_some_and(|s| s.set(if high { Level::High } else { Level::Low }))
    }
}

/// The device.
#[derive(Debug)]
pub struct Pin {
    handle: PinHandle,
}

impl Pin {
    pub fn new(handle: PinHandle) -> Self {
        Self { handle }
    }
}

impl Device for Pin {
    fn class(&self) -> &'static DeviceClass {
        &CLASS
    }

    fn realize(&self, _ctx: &mut RealizeCtx<'_>) -> Result<()> {
        Ok(())
    }

    fn reset(&self, _kind: ResetKind) {}

    fn connect(&self, port: &str, source: WireSource) -> Result<()> {
        if port != "out" {
            return Err(Error::Config {
                at: String::from(CLASS_NAME),
                message: String::from("the only pin is `out`"),
            });
        }
        source.set(Level::Low);
        *self.handle.0.lock().unwrap_or_else(|e| e.into_inner()) = Some(source);
        Ok(())
    }
}

impl Instance for Pin {}

/// The `pil.pin` device class.
pub static CLASS: DeviceClass = DeviceClass {
    name: CLASS_NAME,
    version: 1,
    summary: "an output line driven by the host (cfnav PIL)",
    properties: &[PropertySpec {
        name: "net",
        kind: ValueKind::Str,
        required: false,
        summary: "which line: \"imu-int3\" (default) or \"nrf-rts\"",
    }],
    construct: |_props| Ok(Box::new(Pin::new(PinHandle::default()))),
};

/// What the validator should know about `pil.pin`.
pub fn schema() -> ClassSchema {
    ClassSchema::new(CLASS_NAME)
        .prop(PropSchema::new("net", ValueKind::Str).values(&["imu-int3", "nrf-rts"]))
        .port("out", PortDir::Out)
}

/// Whether an instance is the nRF51's RTS line (`net = "nrf-rts"`).
pub fn is_nrf_rts(props: &Props) -> bool {
    props.get("net").and_then(|v| v.as_str()) == Some("nrf-rts")
}
