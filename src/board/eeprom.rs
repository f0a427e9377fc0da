//! The persistent parameters' EEPROM I/O: the 24AA64 at 0x50 on the deck bus I2C1
//! (`docs/hardware.md` §1, §2), driven for `cfnav::system::persistent_params`.
//!
//! * Boot: [`read_persistent`] reads the two slots ([`REGION_LEN`] bytes from [`REGION_START`]) with
//!   sequential reads of at most `READ_CHUNK_LEN` bytes each (a 16-bit memory address, then the array
//!   auto-increments: 24AA64 datasheet DS21189 §8.3 "Sequential Read"), before the deck task owns the bus.
//!   Chunked because the deck bus guard bounds every transfer to 10 ms and the whole region takes ≈ 29 ms
//!   at 400 kHz: one read of it always timed out (the emulator, `docs/pil.md`, shows it).
//! * Runtime: the radio task hands a prepared write to [`EEPROM_JOB`]; the deck task, which owns I2C1,
//!   calls [`service`] once per tick, writes the slot page by page (≤ 32 bytes, never across a page
//!   boundary: DS21189 §6.2 "Page Write"), waits the write cycle after each page (`TWC` ≤ 5 ms, DS21189
//!   Table 1-2), reads the slot back and signals [`EEPROM_DONE`] with the outcome. A store takes ~120 ms of
//!   deck-bus time, during which the height and Multi-ranger readings pause: the parameter store refuses
//!   persistent writes while flying.
//!
//! Memory: one slot image in the signal (640 bytes) and a read-back buffer on the deck task's stack.

use cfnav::system::config_block::EEPROM_I2C_ADDRESS;
use cfnav::system::persistent_params::{
    PAGE_LEN, PendingWrite, PersistentParams, REGION_LEN, REGION_START, SLOT_LEN, read_chunks,
};
use defmt::{info, warn};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Timer, with_timeout};
use embedded_hal_async::i2c::I2c as _;

use super::i2c_bus::DeckI2c;

/// A persistent store or clear for the deck task to write.
pub static EEPROM_JOB: Signal<CriticalSectionRawMutex, PendingWrite> = Signal::new();
/// The outcome of the latest [`EEPROM_JOB`]: true when written and read back identical.
pub static EEPROM_DONE: Signal<CriticalSectionRawMutex, bool> = Signal::new();

/// Deadline of one EEPROM transfer (a page write or a `READ_CHUNK_LEN` read, ≈ 3 ms at 400 kHz; the
/// guard's own 10 ms deadline and one retry come first).
const TRANSFER_TIMEOUT: Duration = Duration::from_millis(60);

/// Why a chunked read failed.
enum ReadError<E> {
    Bus(E),
    TimedOut,
}

/// Reads `buf.len()` bytes from EEPROM address `start`, one `read_chunks` piece per transfer.
async fn read_at(
    i2c: &mut DeckI2c,
    start: u16,
    buf: &mut [u8],
) -> Result<(), ReadError<<DeckI2c as embedded_hal_async::i2c::ErrorType>::Error>> {
    for (addr, range) in read_chunks(start, buf.len()) {
        match with_timeout(
            TRANSFER_TIMEOUT,
            i2c.write_read(EEPROM_I2C_ADDRESS, &addr.to_be_bytes(), &mut buf[range]),
        )
        .await
        {
            Ok(Ok(())) => {}
            Ok(Err(e)) => return Err(ReadError::Bus(e)),
            Err(_) => return Err(ReadError::TimedOut),
        }
    }
    Ok(())
}
/// The write cycle after each page: `TWC` ≤ 5 ms (DS21189 Table 1-2), plus a margin.
const WRITE_CYCLE: Duration = Duration::from_millis(6);

/// Reads the persistent records at boot; nothing stored (with a warning) if the EEPROM cannot be read.
pub async fn read_persistent(i2c: &mut DeckI2c) -> PersistentParams {
    let mut region = [0u8; REGION_LEN];
    match read_at(i2c, REGION_START, &mut region).await {
        Ok(()) => {
            let (stored, report) = PersistentParams::load(&region);
            info!(
                "persistent parameters: {} stored (slot {}, {})",
                stored.len(),
                report.used,
                defmt::Debug2Format(&report.slots)
            );
            stored
        }
        Err(ReadError::Bus(e)) => {
            warn!(
                "EEPROM read failed ({}): no persistent parameters",
                defmt::Debug2Format(&e)
            );
            PersistentParams::empty()
        }
        Err(ReadError::TimedOut) => {
            warn!("EEPROM read timed out: no persistent parameters");
            PersistentParams::empty()
        }
    }
}

/// Writes `job` page by page and reads it back; true if the EEPROM now holds exactly its bytes.
async fn write(i2c: &mut DeckI2c, job: &PendingWrite) -> bool {
    let mut frame = [0u8; 2 + PAGE_LEN];
    for (addr, page) in job.pages() {
        frame[..2].copy_from_slice(&addr.to_be_bytes());
        frame[2..2 + page.len()].copy_from_slice(page);
        let sent = with_timeout(
            TRANSFER_TIMEOUT,
            i2c.write(EEPROM_I2C_ADDRESS, &frame[..2 + page.len()]),
        )
        .await;
        if !matches!(sent, Ok(Ok(()))) {
            warn!("EEPROM page write at {=u16:#x} failed", addr);
            return false;
        }
        Timer::after(WRITE_CYCLE).await;
    }
    let mut back = [0u8; SLOT_LEN];
    let read = read_at(i2c, job.address(), &mut back).await;
    read.is_ok() && back == *job.bytes()
}

/// Called by the deck task once per tick: does the waiting write, if any.
pub async fn service(i2c: &mut DeckI2c) {
    if let Some(job) = EEPROM_JOB.try_take() {
        let ok = write(i2c, &job).await;
        if ok {
            info!("persistent parameters written (slot {})", job.slot());
        }
        EEPROM_DONE.signal(ok);
    }
}
