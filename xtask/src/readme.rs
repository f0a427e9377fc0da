//! The README's commands as written: every non-comment line of every ```` ```sh ```` block, run from the
//! repository root by bash, must exit 0.
//!
//! - Lines whose command is `cfloader ...` or `cargo fw-run ...` need the hardware: printed as skipped.
//! - A line ending in ` &` starts a background process (its own process group), stopped at the end of its
//!   block. One that serves the simulator (`sim --serve`, `pil --serve`) must answer cflib's scan probe on
//!   its port (`--port N`, default 19850) before the block's next line runs.
//! - Anything else the README shows only as an example (placeholders such as `[--opt X]`) belongs in a
//!   ```` ```text ```` block, which this step does not read.

use std::net::UdpSocket;
use std::path::Path;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

/// One command line of a ```` ```sh ```` block.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Line {
    /// 1-based line number in the file.
    pub number: usize,
    /// The line as written (trimmed).
    pub text: String,
    /// Which block (0-based) it belongs to.
    pub block: usize,
}

/// The command lines of every ```` ```sh ```` block, in order (blank lines and `#` comment lines left out).
pub fn sh_lines(text: &str) -> Vec<Line> {
    let mut out = Vec::new();
    let mut block: Option<usize> = None;
    let mut blocks = 0;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if let Some(b) = block {
            if line.starts_with("```") {
                block = None;
            } else if !line.is_empty() && !line.starts_with('#') {
                out.push(Line {
                    number: i + 1,
                    text: line.to_string(),
                    block: b,
                });
            }
        } else if let Some(info) = line.strip_prefix("```") {
            if info.trim() == "sh" {
                block = Some(blocks);
                blocks += 1;
            } else if !info.trim().is_empty() {
                // Another language's block: skip to its closing fence.
                block = None;
            }
        }
    }
    out
}

/// The line without a trailing shell comment (` # ...` outside quotes).
pub fn command_part(line: &str) -> &str {
    let (mut single, mut double) = (false, false);
    let bytes = line.as_bytes();
    for (i, &c) in bytes.iter().enumerate() {
        match c {
            b'\'' if !double => single = !single,
            b'"' if !single => double = !double,
            b'#' if !single && !double && (i == 0 || bytes[i - 1].is_ascii_whitespace()) => {
                return line[..i].trim_end();
            }
            _ => {}
        }
    }
    line.trim_end()
}

/// What to do with a line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Action {
    /// Needs the hardware (`cfloader`, `cargo fw-run`).
    Skip,
    /// Run in the foreground: must exit 0.
    Run(String),
    /// Start in the background (the command without its `&`); `Some(port)` if it serves the simulator.
    Background(String, Option<u16>),
}

pub fn action(line: &str) -> Action {
    let cmd = command_part(line);
    let words: Vec<&str> = cmd.split_whitespace().collect();
    if words.first() == Some(&"cfloader") || words.starts_with(&["cargo", "fw-run"]) {
        return Action::Skip;
    }
    match cmd.strip_suffix(" &") {
        Some(bg) => {
            let bg = bg.trim_end().to_string();
            let serves = words
                .windows(2)
                .any(|w| w[1] == "--serve" && (w[0] == "sim" || w[0] == "pil"));
            let port = words
                .windows(2)
                .find(|w| w[0] == "--port")
                .and_then(|w| w[1].parse().ok())
                .unwrap_or(DEFAULT_PORT);
            Action::Background(bg, serves.then_some(port))
        }
        None => Action::Run(cmd.to_string()),
    }
}

/// `cfnav sim --serve`'s port when none is given.
pub const DEFAULT_PORT: u16 = 19850;

/// Whether 127.0.0.1:`port` answers a bare 0xFF datagram (cflib's scan) within `wait`.
pub fn answers_scan_probe(port: u16, wait: Duration) -> bool {
    let deadline = Instant::now() + wait;
    while Instant::now() < deadline {
        if let Ok(s) = UdpSocket::bind("127.0.0.1:0") {
            let _ = s.set_read_timeout(Some(Duration::from_millis(200)));
            let mut buf = [0u8; 64];
            if s.send_to(&[0xFF], ("127.0.0.1", port)).is_ok() && s.recv(&mut buf).is_ok() {
                return true;
            }
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    false
}

/// How long a background simulator may take to answer (it may have to be built first).
const SERVE_WAIT: Duration = Duration::from_secs(600);

fn bash(cmd: &str, root: &Path) -> Command {
    let mut c = Command::new("bash");
    c.arg("-c").arg(cmd).current_dir(root);
    c
}

fn stop(children: &mut Vec<(String, Child)>) {
    for (cmd, child) in children.iter_mut() {
        // Its own process group (see `run`): the group goes, with `cargo run`'s child.
        let _ = Command::new("kill")
            .arg("--")
            .arg(format!("-{}", child.id()))
            .stderr(std::process::Stdio::null())
            .status();
        let _ = child.wait();
        println!("stopped: {cmd}");
    }
    children.clear();
}

/// Runs the `lines` from `root`, printing each; the number of lines run, or every failure (one line each,
/// with its place in `file`). After a failure the rest of that block is left out (its lines may need the
/// failed one) and the next block runs. A foreground line equal to one of `already` (commands an earlier
/// step of the same CI run ran, verbatim, and saw exit 0) is counted as run, not run again.
pub fn run(file: &str, lines: &[Line], root: &Path, already: &[String]) -> Result<usize, String> {
    use std::os::unix::process::CommandExt;
    let mut background: Vec<(String, Child)> = Vec::new();
    let mut ran = 0;
    let mut failures: Vec<String> = Vec::new();
    let mut failed_block = None;
    for (i, line) in lines.iter().enumerate() {
        let at = format!("{file}:{}", line.number);
        let block_ends = lines.get(i + 1).is_none_or(|next| next.block != line.block);
        if failed_block == Some(line.block) {
            println!("{at}: left out (an earlier line of its block failed): {}", line.text);
            continue;
        }
        let mut failure = None;
        match action(&line.text) {
            Action::Skip => println!("{at}: skipped (needs the hardware): {}", line.text),
            Action::Run(cmd) if already.iter().any(|a| a == cmd.trim()) => {
                println!("{at}: $ {cmd}  (an earlier step of this run ran it verbatim: exit 0)");
                ran += 1;
            }
            Action::Run(cmd) => {
                println!("{at}: $ {cmd}");
                let status = bash(&cmd, root).status().map_err(|e| format!("{at}: bash: {e}"))?;
                ran += 1;
                if !status.success() {
                    failure = Some(format!("{at}: `{}` exited with {status}", line.text));
                }
            }
            Action::Background(cmd, port) => {
                println!("{at}: $ {cmd} &");
                let mut c = bash(&format!("exec {cmd}"), root);
                c.process_group(0);
                let child = c.spawn().map_err(|e| format!("{at}: bash: {e}"))?;
                ran += 1;
                background.push((cmd.clone(), child));
                if let Some(port) = port {
                    failure = wait_until_served(&at, &line.text, port, &mut background);
                }
            }
        }
        if let Some(f) = failure {
            println!("FAILED {f}");
            failures.push(f);
            failed_block = Some(line.block);
        }
        if block_ends || failed_block == Some(line.block) {
            stop(&mut background);
        }
    }
    if failures.is_empty() {
        Ok(ran)
    } else {
        Err(failures.join("\n"))
    }
}

/// Waits until the last background process answers on `port`; `Some(failure)` if it ends or never does.
fn wait_until_served(at: &str, text: &str, port: u16, background: &mut [(String, Child)]) -> Option<String> {
    let started = Instant::now();
    while started.elapsed() < SERVE_WAIT {
        if answers_scan_probe(port, Duration::from_secs(2)) {
            println!("{at}: answers on udp://127.0.0.1:{port}");
            return None;
        }
        if let Some((_, child)) = background.last_mut()
            && let Ok(Some(status)) = child.try_wait()
        {
            return Some(format!("{at}: `{text}` ended ({status}) before it answered"));
        }
    }
    Some(format!("{at}: `{text}` does not answer on port {port}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIXTURE: &str = "# A README\n\
        \n\
        ```sh\n\
        true                       # a comment after the command\n\
        # a comment line\n\
        \n\
        cfloader flash target/cf2.bin stm32-fw\n\
        cargo fw-run\n\
        ```\n\
        \n\
        ```text\n\
        cargo run -- plan [--json FILE]\n\
        ```\n\
        \n\
        ```sh\n\
        sleep 30 &\n\
        test -f marker || touch marker\n\
        ```\n";

    #[test]
    fn only_sh_blocks_are_read_and_comments_are_left_out() {
        let lines = sh_lines(FIXTURE);
        let texts: Vec<&str> = lines.iter().map(|l| l.text.as_str()).collect();
        assert_eq!(
            texts,
            [
                "true                       # a comment after the command",
                "cfloader flash target/cf2.bin stm32-fw",
                "cargo fw-run",
                "sleep 30 &",
                "test -f marker || touch marker",
            ]
        );
        assert_eq!(lines[0].number, 4);
        assert_eq!((lines[2].block, lines[3].block), (0, 1));
    }

    #[test]
    fn actions_follow_the_convention() {
        assert_eq!(action("cfloader flash x stm32-fw"), Action::Skip);
        assert_eq!(action("cargo fw-run   # with a probe"), Action::Skip);
        assert_eq!(action("cargo fw"), Action::Run("cargo fw".into()));
        assert_eq!(
            action("echo '# not a comment'"),
            Action::Run("echo '# not a comment'".into())
        );
        assert_eq!(
            action("cargo run --release -p cfnav-tools -- sim --serve --speed 20 &"),
            Action::Background(
                "cargo run --release -p cfnav-tools -- sim --serve --speed 20".into(),
                Some(19850)
            )
        );
        assert_eq!(
            action("cfnav sim --serve --port 19999 & # served"),
            Action::Background("cfnav sim --serve --port 19999".into(), Some(19999))
        );
        assert_eq!(action("sleep 5 &"), Action::Background("sleep 5".into(), None));
    }

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("xtask-readme-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_passing_readme_runs_every_line_and_stops_its_background_process() {
        let dir = scratch("pass");
        let lines = sh_lines(FIXTURE);
        // true, sleep &, test/touch: three lines run, two skipped.
        assert_eq!(run("README.md", &lines, &dir, &[]), Ok(3));
        assert!(dir.join("marker").exists(), "the line ran from the given root");
        let sleeping = Command::new("pgrep").args(["-f", "^sleep 30$"]).output().unwrap();
        assert!(sleeping.stdout.is_empty(), "the background `sleep 30` was not stopped");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_failing_line_fails_with_its_line_number() {
        let dir = scratch("fail");
        let text = "```sh\ntrue\nexit 3\ntouch never\n```\n\n```sh\ntouch next\nfalse\n```\n";
        let err = run("README.md", &sh_lines(text), &dir, &[]).unwrap_err();
        let failures: Vec<&str> = err.lines().collect();
        assert_eq!(failures.len(), 2, "{err}");
        assert!(failures[0].starts_with("README.md:3: `exit 3` exited"), "{err}");
        assert!(failures[1].starts_with("README.md:9: `false` exited"), "{err}");
        assert!(
            !dir.join("never").exists(),
            "lines after the failure in its block must not run"
        );
        assert!(dir.join("next").exists(), "the next block runs after a failed one");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_server_that_dies_before_answering_fails() {
        let dir = scratch("serve");
        let text = "```sh\nbash -c 'exit 1' sim --serve --port 19998 &\ntrue\n```\n";
        let err = run("README.md", &sh_lines(text), &dir, &[]).unwrap_err();
        assert!(err.contains("before it answered"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_line_an_earlier_step_ran_verbatim_is_not_run_twice() {
        let dir = scratch("already");
        let text = "```sh\ntouch once\ntouch twice\n```\n";
        let already = ["touch once".to_string()];
        assert_eq!(run("README.md", &sh_lines(text), &dir, &already), Ok(2));
        assert!(
            !dir.join("once").exists(),
            "a command an earlier step ran is counted, not run again"
        );
        assert!(dir.join("twice").exists(), "every other line runs");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
