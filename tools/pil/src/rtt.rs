//! The defmt log, read out of the image's RTT up-buffer 0 as a debug probe would, and decoded with the ELF's
//! `.defmt` table (`defmt-decoder`).
//!
//! SEGGER RTT control block layout (as defmt-rtt 1.x lays it out): `id[16]`, `max_up_buffers: u32`,
//! `max_down_buffers: u32`, then the up-buffer descriptors `{name, buffer, size, write, read, flags}` (six
//! u32). The host reads `[read, write)` and advances `read`, exactly like probe-rs.
//!
//! Non-goals: no down channel, no blocking mode.

use crate::board::Board;

/// Offset of up-buffer 0's descriptor in the control block.
const UP0: u64 = 24;

/// One decoded log line.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LogLine {
    /// Virtual time the host read it (ns since power-on).
    pub read_at_ns: u64,
    /// The line as `defmt-print` shows it (timestamp, level, message).
    pub text: String,
    pub level: Option<String>,
}

/// The reader.
pub struct Rtt<'t> {
    block: u64,
    decoder: Box<dyn defmt_decoder::StreamDecoder + Send + Sync + 't>,
    pub lines: Vec<LogLine>,
    pub bytes: usize,
    pub malformed: usize,
}

impl<'t> Rtt<'t> {
    pub fn new(block: u64, table: &'t defmt_decoder::Table) -> Self {
        Self {
            block,
            decoder: table.new_stream_decoder(),
            lines: Vec::new(),
            bytes: 0,
            malformed: 0,
        }
    }

    /// Drains what the firmware has written since the last call; returns the new lines.
    pub fn poll(&mut self, board: &Board) -> &[LogLine] {
        let first_new = self.lines.len();
        let desc = self.block + UP0;
        let (Some(buffer), Some(size), Some(write), Some(read)) = (
            board.peek32(desc + 4),
            board.peek32(desc + 8),
            board.peek32(desc + 12),
            board.peek32(desc + 16),
        ) else {
            return &[];
        };
        // Before defmt-rtt's control block is initialised (the .data copy at reset) everything reads 0.
        if size == 0 || write >= size || read >= size || write == read {
            return &[];
        }
        let mut data = Vec::new();
        let mut at = read;
        while at != write {
            match board.peek8(u64::from(buffer) + u64::from(at)) {
                Some(b) => data.push(b),
                None => return &[],
            }
            at = (at + 1) % size;
        }
        board.poke32(desc + 16, write);
        self.bytes += data.len();
        self.decoder.received(&data);
        let now = board.now_ns();
        loop {
            match self.decoder.decode() {
                Ok(frame) => self.lines.push(LogLine {
                    read_at_ns: now,
                    text: frame.display(false).to_string(),
                    level: frame.level().map(|l| format!("{l:?}").to_lowercase()),
                }),
                Err(defmt_decoder::DecodeError::UnexpectedEof) => break,
                Err(defmt_decoder::DecodeError::Malformed) => {
                    self.malformed += 1;
                    break;
                }
            }
        }
        &self.lines[first_new..]
    }
}
