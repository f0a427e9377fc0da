//! A scripted radio host inside the emulator: cflib's connect sequence as a fixed
//! list of CRTP requests, each sent when the previous one was answered (cflib waits for every TOC answer the
//! same way), all on **virtual** time, so a run is deterministic and reproduces what a real cflib did over UDP
//! without the wall clock.
//!
//! Job: hand the nRF51 end (`nrf51.rs`) the next request once the image answered the last one (or at
//! `start_ms`), match the image's downlink packets against the expected answer, record when each came.
//! Non-goals: retries (cflib's UDP driver has none), decoding the answers beyond the match.
//! Units: virtual ms. Memory: the request list (a few hundred 4-byte packets).
//!
//! Sequences (`--client`): `toc` = link source, protocol version, log reset, log TOC info, every log TOC item,
//! param TOC info, every param TOC item, then every parameter's value (what `SyncCrazyflie` does with no
//! cache, docs/radio.md), optionally repeated (`toc:N`) so a long run shows a stall; `early` = the same,
//! `toc:N:GAP` waits GAP virtual ms after each answer before the next request (cflib's pacing over a slow link).
//! `burst:N` = N log TOC item requests handed over at once (pipelined, as a raw-UDP probe sends them), so the
//! nRF forwards one per ms: the image answers back to back.

use serde::Serialize;

/// CRTP header for port/channel with the link bits set as cflib sets them (`crtpstack.py`: `3 << 2`).
fn header(port: u8, channel: u8) -> u8 {
    (port & 0x0F) << 4 | 0x0C | (channel & 0x03)
}

/// One request and the prefix of the answer that completes it (port, channel and leading data bytes).
#[derive(Debug, Clone)]
struct Request {
    packet: Vec<u8>,
    answer_header: u8,
    answer_prefix: Vec<u8>,
    what: &'static str,
}

/// What the client saw, for the report.
#[derive(Debug, Default, Clone, Serialize)]
pub struct ClientStats {
    /// Requests sent to the nRF end.
    pub sent: u64,
    /// Requests answered.
    pub answered: u64,
    /// Virtual ms of the first request.
    pub first_request_ms: Option<u64>,
    /// Virtual ms of the last answer.
    pub last_answer_ms: Option<u64>,
    /// The request waiting for its answer at the end, if any ("what" and its index).
    pub stalled_on: Option<String>,
    /// Log and param TOC sizes, as the image announced them.
    pub log_toc: Option<u16>,
    pub param_toc: Option<u16>,
    /// Every request of the sequence was answered.
    pub done: bool,
}

/// The scripted host.
#[derive(Debug)]
pub struct Client {
    start_ms: u64,
    /// Before RADIO_READY (`early`): the first requests are queued at start_ms whatever the image does.
    repeat: u32,
    queue: Vec<Request>,
    next: usize,
    waiting: Option<usize>,
    phase: u32,
    /// `burst:N`: requests handed over at once, answers counted as they come.
    burst: u16,
    /// `toc:N:GAP`: virtual ms between an answer and the next request (cflib's wall-clock pacing).
    gap_ms: u64,
    next_at_ms: u64,
    /// Counters.
    pub stats: ClientStats,
}

impl Client {
    /// Parses `toc`, `toc:N` (N rounds) with a start time in virtual ms.
    pub fn new(spec: &str, start_ms: u64) -> Result<Self, String> {
        let (name, rest) = spec.split_once(':').unwrap_or((spec, "1"));
        let (rounds, gap) = rest.split_once(':').unwrap_or((rest, "0"));
        let gap_ms: u64 = gap
            .parse()
            .ok()
            .filter(|&g| g <= 1000)
            .ok_or_else(|| format!("--client {spec}: GAP must be 0..=1000 ms"))?;
        if name == "burst" {
            let n: u16 = rounds
                .parse()
                .ok()
                .filter(|&n| (1..=1000).contains(&n))
                .ok_or_else(|| format!("--client {spec}: N must be 1..=1000"))?;
            return Ok(Self {
                start_ms,
                repeat: 1,
                queue: Vec::new(),
                next: 0,
                waiting: None,
                phase: 0,
                burst: n,
                gap_ms: 0,
                next_at_ms: 0,
                stats: ClientStats::default(),
            });
        }
        if name != "toc" {
            return Err(format!(
                "unknown --client `{spec}` (known: toc, toc:N, toc:N:GAP, burst:N)"
            ));
        }
        let repeat: u32 = rounds
            .parse()
            .ok()
            .filter(|&n| (1..=100).contains(&n))
            .ok_or_else(|| format!("--client {spec}: N must be 1..=100"))?;
        let mut c = Self {
            start_ms,
            repeat,
            queue: Vec::new(),
            next: 0,
            waiting: None,
            phase: 0,
            burst: 0,
            gap_ms,
            next_at_ms: 0,
            stats: ClientStats::default(),
        };
        c.queue = Self::opening();
        Ok(c)
    }

    /// The requests whose count does not depend on the image: link source, version, log reset and TOC info.
    fn opening() -> Vec<Request> {
        let req = |port: u8, ch: u8, data: &[u8], prefix: &[u8], what| Request {
            packet: [&[header(port, ch)][..], data].concat(),
            answer_header: header(port, ch),
            answer_prefix: prefix.to_vec(),
            what,
        };
        vec![
            req(15, 1, &[0], &[], "link source"),
            req(13, 1, &[0], &[0], "protocol version"),
            req(5, 1, &[5], &[5], "log reset"),
            req(5, 0, &[3], &[3], "log TOC info"),
            req(2, 0, &[3], &[3], "param TOC info"),
        ]
    }

    /// Called once per host slice: the request to send now, if one is due.
    pub fn poll(&mut self, now_ms: u64) -> Option<Vec<u8>> {
        if self.burst > 0 {
            // One request per call until all N are out (the caller calls once per 1 ms slice and the nRF queues
            // them: the image sees them back to back once its receiver is on).
            if now_ms < self.start_ms || self.stats.sent >= u64::from(self.burst) {
                return None;
            }
            let [lo, hi] = (self.stats.sent as u16 % 50).to_le_bytes();
            self.stats.sent += 1;
            self.stats.first_request_ms.get_or_insert(now_ms);
            return Some(vec![header(5, 0), 2, lo, hi]);
        }
        if now_ms < self.start_ms.max(self.next_at_ms) || self.waiting.is_some() || self.stats.done {
            return None;
        }
        if self.next >= self.queue.len() {
            self.phase += 1;
            if self.phase >= self.repeat {
                self.stats.done = true;
                return None;
            }
            self.queue = Self::opening();
            self.next = 0;
        }
        let r = &self.queue[self.next];
        self.waiting = Some(self.next);
        self.next += 1;
        self.stats.sent += 1;
        self.stats.first_request_ms.get_or_insert(now_ms);
        Some(r.packet.clone())
    }

    /// A CRTP packet the image sent to the host.
    pub fn on_downlink(&mut self, crtp: &[u8], now_ms: u64) {
        if self.burst > 0 {
            if crtp.first().is_some_and(|&h| h & 0xF3 == header(5, 0) & 0xF3) {
                self.stats.answered += 1;
                self.stats.last_answer_ms = Some(now_ms);
                self.stats.done = self.stats.answered >= u64::from(self.burst);
            }
            return;
        }
        let Some(i) = self.waiting else { return };
        let r = &self.queue[i];
        let Some((&h, data)) = crtp.split_first() else { return };
        if h & 0xF3 != r.answer_header & 0xF3 || !data.starts_with(&r.answer_prefix) {
            return;
        }
        let what = r.what;
        self.waiting = None;
        self.next_at_ms = now_ms + self.gap_ms;
        self.stats.answered += 1;
        self.stats.last_answer_ms = Some(now_ms);
        let count = || data.get(1..3).map(|b| u16::from_le_bytes([b[0], b[1]]));
        match what {
            "log TOC info" => {
                let n = count().unwrap_or(0);
                self.stats.log_toc = Some(n);
                // GET_ITEM_V2 (cmd 2, u16 index) for every variable, then the param TOC info already queued.
                let items = (0..n).map(|i| {
                    let [lo, hi] = i.to_le_bytes();
                    Request {
                        packet: vec![header(5, 0), 2, lo, hi],
                        answer_header: header(5, 0),
                        answer_prefix: vec![2, lo, hi],
                        what: "log TOC item",
                    }
                });
                let at = self.next;
                self.queue.splice(at..at, items);
            }
            "param TOC info" => {
                let n = count().unwrap_or(0);
                self.stats.param_toc = Some(n);
                let items = (0..n).map(|i| {
                    let [lo, hi] = i.to_le_bytes();
                    Request {
                        packet: vec![header(2, 0), 2, lo, hi],
                        answer_header: header(2, 0),
                        answer_prefix: vec![2, lo, hi],
                        what: "param TOC item",
                    }
                });
                // Then every value (param port 2, channel 1, u16 id): what `fully_connected` waits for.
                let values = (0..n).map(|i| {
                    let [lo, hi] = i.to_le_bytes();
                    Request {
                        packet: vec![header(2, 1), lo, hi],
                        answer_header: header(2, 1),
                        answer_prefix: vec![lo, hi],
                        what: "param value",
                    }
                });
                let at = self.next;
                let all: Vec<_> = items.chain(values).collect();
                self.queue.splice(at..at, all);
            }
            _ => {}
        }
    }

    /// Fills `stalled_on` for the report.
    pub fn finish(&mut self) {
        if let Some(i) = self.waiting {
            self.stats.stalled_on = Some(format!(
                "{} (request {} of round {}, {:02x?})",
                self.queue[i].what,
                i,
                self.phase + 1,
                self.queue[i].packet
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lockstep_and_toc_expansion() {
        let mut c = Client::new("toc", 10).unwrap();
        assert_eq!(c.poll(5), None, "not before start");
        assert_eq!(c.poll(10), Some(vec![0xFD, 0]));
        assert_eq!(c.poll(11), None, "waits for the answer");
        c.on_downlink(&[0xF0, 0], 12); // port 15 channel 0: not the answer
        assert_eq!(c.poll(12), None);
        c.on_downlink(&[0xFD, b'B'], 12);
        assert_eq!(c.poll(13), Some(vec![0xDD, 0]));
        c.on_downlink(&[0xDD, 0, 12], 14);
        assert_eq!(c.poll(15), Some(vec![0x5D, 5]));
        c.on_downlink(&[0x5D, 5, 0], 16);
        assert_eq!(c.poll(17), Some(vec![0x5C, 3]));
        c.on_downlink(&[0x5C, 3, 2, 0, 1, 2, 3, 4], 18);
        assert_eq!(c.stats.log_toc, Some(2));
        assert_eq!(c.poll(19), Some(vec![0x5C, 2, 0, 0]));
        c.on_downlink(&[0x5C, 2, 0, 0, 7], 20);
        assert_eq!(c.poll(21), Some(vec![0x5C, 2, 1, 0]));
        c.on_downlink(&[0x5C, 2, 1, 0, 7], 22);
        assert_eq!(c.poll(23), Some(vec![0x2C, 3]));
        c.on_downlink(&[0x2C, 3, 1, 0, 9, 9, 9, 9], 24);
        assert_eq!(c.poll(25), Some(vec![0x2C, 2, 0, 0]));
        c.on_downlink(&[0x2C, 2, 0, 0, 8], 26);
        assert_eq!(c.poll(27), Some(vec![0x2D, 0, 0]));
        c.on_downlink(&[0x2D, 0, 0, 1], 28);
        assert_eq!(c.poll(29), None);
        assert!(c.stats.done);
        assert_eq!(c.stats.answered, 9);
    }
}
