//! The CI steps, in the order a full run takes them. Each is a function of the [`Ci`] context that returns
//! `Err(why)` when its check fails. Budgets and bounds are constants here, passed explicitly to the tools
//! (the tools' own defaults are the chip's limits).

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use cfnav_tools::firmware::{MemoryUse, build_image, read_elf};
use cfnav_tools::sim::cli::Summary;
use cfnav_tools::sim::runner::RunReport;

use crate::expected::{self, Figure};
use crate::readme;

/// CI's flash guard, KiB: room for the next few flight rules over today's image, still catching a
/// dependency or a debug build that balloons it (the chip's application region is 1008 KiB).
pub const FLASH_BUDGET_KIB: u32 = 288;
/// CI's static SRAM guard, KiB (of 128 KiB; the stack takes the rest).
pub const RAM_BUDGET_KIB: u32 = 100;
/// The largest stack frame CI accepts, bytes: the ≈ 57 KB navigator built by value once took a 104 KB
/// frame and overran the stack into .bss at boot; it is written in place now (`Navigator::init_at`).
pub const STACK_FRAME_BUDGET: u64 = 32 * 1024;
/// Property tests run a fixed sequence of cases in CI (a local `cargo test` draws new ones every run).
const PROPTEST_RNG_SEED: &str = "20261122";
/// The bootloader's sector: no LOAD segment may start inside it, by virtual or physical address.
const BOOTLOADER: std::ops::Range<u64> = 0x0800_0000..0x0800_4000;

pub type StepFn = fn(&mut Ci) -> Result<(), String>;
pub type Finish = Box<dyn FnOnce(&mut Ci) -> Result<(), String>>;

/// A named step.
pub struct Step {
    pub name: &'static str,
    pub about: &'static str,
    pub run: StepFn,
}

/// Every step, in order.
pub const STEPS: &[Step] = &[
    Step {
        name: "format",
        about: "cargo fmt --check (both workspaces)",
        run: format,
    },
    Step {
        name: "clippy-host",
        about: "clippy -D warnings on the host (both workspaces)",
        run: clippy_host,
    },
    Step {
        name: "clippy-thumb",
        about: "clippy -D warnings for thumbv7em-none-eabihf (firmware, qemu-bench)",
        run: clippy_thumb,
    },
    Step {
        name: "test-host",
        about: "cargo test -p host-tests (the README's test command)",
        run: test_host,
    },
    Step {
        name: "test-tools",
        about: "cargo test -p cfnav-tools, -p cfnav-sim and -p xtask",
        run: test_tools,
    },
    Step {
        name: "firmware",
        about: "image, budgets, objcopy identity, LOAD segments, stack frame, ci/expected/firmware.txt",
        run: firmware,
    },
    Step {
        name: "planner",
        about: "planner replay on every example map (exit status and report as each map expects)",
        run: planner,
    },
    Step {
        name: "qemu",
        about: "Cortex-M4 instruction counts under QEMU: targets and ci/expected/qemu-bench.txt",
        run: qemu,
    },
    Step {
        name: "sim-worlds",
        about: "simulator: default world, failure worlds, every shipped world",
        run: sim_worlds,
    },
    Step {
        name: "sim-batches",
        about: "simulator batches (classic seed 1, wide seed 100 default and stressed): bounds and ci/expected/sim-*.txt",
        run: sim_batches,
    },
    Step {
        name: "readme",
        about: "every command line of README.md's ```sh blocks exits 0 as written",
        run: readme_step,
    },
    Step {
        name: "cfclient",
        about: "stock cfclient under Xvfb and cflib's stock names (sim --serve)",
        run: cfclient,
    },
    Step {
        name: "pil",
        about: "emulator: build, tests, unmodified cflib over UDP, then its runs in the background (checked last)",
        run: pil,
    },
    Step {
        name: "fuzz",
        about: "cargo-fuzz, 20 s per radio target",
        run: fuzz,
    },
    Step {
        name: "e2e-cflib",
        about: "cflib end-to-end mission over UDP (sim --serve)",
        run: e2e_cflib,
    },
    Step {
        name: "e2e-mission-start",
        about: "cfnav mission start over UDP (crazyflie-lib)",
        run: e2e_mission_start,
    },
    Step {
        name: "e2e-high-level",
        about: "cflib HighLevelCommander over UDP",
        run: e2e_high_level,
    },
    Step {
        name: "e2e-persistent",
        about: "cflib persistent parameters over UDP (sim --param-store)",
        run: e2e_persistent,
    },
    Step {
        name: "e2e-motion",
        about: "cflib MotionCommander and PositionHlCommander over UDP",
        run: e2e_motion,
    },
    Step {
        name: "e2e-setpoint-modes",
        about: "low-level commander, mission modes, link loss, bad writes over UDP",
        run: e2e_setpoint_modes,
    },
    Step {
        name: "e2e-map",
        about: "the map on the PC: cfnav map and cflib's memory API",
        run: e2e_map,
    },
    Step {
        name: "e2e-sequence",
        about: "cflib flies by hand, then the hover test lands where it took off; a round trip off its pad",
        run: e2e_sequence,
    },
];

/// The steps that own an expected file (`cargo xtask bless NAME`).
pub const BLESSABLE: [&str; 3] = ["firmware", "qemu", "sim-batches"];

/// What the steps share: the repository, the target directory, the background work.
pub struct Ci {
    pub root: PathBuf,
    pub target: PathBuf,
    pub bless: bool,
    started: Instant,
    deferred: Vec<(&'static str, &'static str, Finish)>,
    /// Background process groups to stop when CI ends.
    background: Vec<Child>,
    /// The command lines that exited 0 in this run (`program args…`), so the README step can count a line
    /// an earlier step ran verbatim instead of running the same command twice (seeded from
    /// `CFNAV_CI_PASSED`, one command a line, by `.ci/run`).
    passed: std::cell::RefCell<Vec<String>>,
}

impl Ci {
    pub fn new(root: PathBuf, bless: bool) -> Self {
        let target = std::env::var_os("CARGO_TARGET_DIR")
            .map(PathBuf::from)
            .map(|t| if t.is_absolute() { t } else { root.join(t) })
            .unwrap_or_else(|| root.join("target"));
        Self {
            root,
            target,
            bless,
            started: Instant::now(),
            deferred: Vec::new(),
            background: Vec::new(),
            // `.ci/run` runs the README's test command itself before the steps and names it here.
            passed: std::cell::RefCell::new(
                std::env::var("CFNAV_CI_PASSED")
                    .unwrap_or_default()
                    .lines()
                    .map(str::to_string)
                    .collect(),
            ),
        }
    }

    pub fn section(&self, name: &str, about: &str) {
        println!(
            "\n=== {name}: {about}  [{} s into CI]",
            self.started.elapsed().as_secs()
        );
    }

    pub fn take_deferred(&mut self) -> Vec<(&'static str, &'static str, Finish)> {
        std::mem::take(&mut self.deferred)
    }

    /// A command run from the repository root with CI's environment.
    fn cmd(&self, program: &str, args: &[&str]) -> Command {
        let mut c = Command::new(program);
        c.args(args)
            .current_dir(&self.root)
            .env("CARGO_TERM_COLOR", "never")
            .env("PROPTEST_RNG_SEED", PROPTEST_RNG_SEED);
        c
    }

    /// Runs a command, printing it; its exit status.
    fn status(&self, program: &str, args: &[&str]) -> Result<ExitStatus, String> {
        println!("+ {program} {}", args.join(" "));
        self.cmd(program, args).status().map_err(|e| format!("{program}: {e}"))
    }

    /// Runs a command that must exit 0.
    fn run(&self, program: &str, args: &[&str]) -> Result<(), String> {
        let s = self.status(program, args)?;
        if s.success() {
            self.passed.borrow_mut().push(format!("{program} {}", args.join(" ")));
            Ok(())
        } else {
            Err(format!("`{program} {}` exited with {s}", args.join(" ")))
        }
    }

    /// Runs a command that must exit 0 and returns its standard output (also printed).
    fn output(&self, program: &str, args: &[&str]) -> Result<String, String> {
        println!("+ {program} {}", args.join(" "));
        let out = self
            .cmd(program, args)
            .stderr(Stdio::inherit())
            .output()
            .map_err(|e| format!("{program}: {e}"))?;
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        print!("{text}");
        if out.status.success() {
            Ok(text)
        } else {
            Err(format!("`{program} {}` exited with {}", args.join(" "), out.status))
        }
    }

    /// `cfnav` (the release build of cfnav-tools) with `args`; its exit code.
    fn cfnav(&self, args: &[&str]) -> Result<i32, String> {
        let mut all = vec!["run", "-q", "--release", "-p", "cfnav-tools", "--"];
        all.extend_from_slice(args);
        self.status("cargo", &all)?
            .code()
            .ok_or_else(|| "cfnav killed by a signal".into())
    }

    fn cfnav_ok(&self, args: &[&str]) -> Result<(), String> {
        match self.cfnav(args)? {
            0 => Ok(()),
            c => Err(format!("`cfnav {}` exited {c}", args.join(" "))),
        }
    }

    fn release_cfnav(&self) -> String {
        self.target.join("release/cfnav").display().to_string()
    }

    fn elf(&self) -> PathBuf {
        self.target.join("thumbv7em-none-eabihf/release/firmware")
    }

    /// Starts a command in the background in its own process group (stopped by [`Ci::stop_background`]).
    fn spawn(&mut self, program: &str, args: &[&str]) -> Result<u32, String> {
        use std::os::unix::process::CommandExt;
        println!("+ {program} {} &", args.join(" "));
        let child = self
            .cmd(program, args)
            .process_group(0)
            .spawn()
            .map_err(|e| format!("{program}: {e}"))?;
        let id = child.id();
        self.background.push(child);
        Ok(id)
    }

    /// Stops one background process group started by [`Ci::spawn`].
    fn stop(&mut self, id: u32) {
        if let Some(i) = self.background.iter().position(|c| c.id() == id) {
            let mut child = self.background.remove(i);
            let _ = Command::new("kill")
                .arg("--")
                .arg(format!("-{id}"))
                .stderr(Stdio::null())
                .status();
            let _ = child.wait();
        }
    }

    pub fn stop_background(&mut self) {
        let ids: Vec<u32> = self.background.iter().map(Child::id).collect();
        for id in ids {
            self.stop(id);
        }
    }

    fn path(&self, rel: &str) -> PathBuf {
        self.root.join(rel)
    }

    fn mkdir(&self, rel: &str) -> Result<(), String> {
        fs::create_dir_all(self.path(rel)).map_err(|e| format!("{rel}: {e}"))
    }
}

impl Drop for Ci {
    fn drop(&mut self) {
        self.stop_background();
    }
}

fn ensure(cond: bool, message: impl FnOnce() -> String) -> Result<(), String> {
    if cond { Ok(()) } else { Err(message()) }
}

fn format(ci: &mut Ci) -> Result<(), String> {
    ci.run("cargo", &["fmt", "--all", "--check"])?;
    // The emulator is its own workspace (it builds rsemu with a fix applied: tools/pil/cargo.sh).
    ci.run("bash", &["tools/pil/cargo.sh", "fmt", "--all", "--check"])
}

fn clippy_host(ci: &mut Ci) -> Result<(), String> {
    ci.run(
        "cargo",
        &["clippy", "--workspace", "--all-targets", "--", "-D", "warnings"],
    )?;
    ci.run(
        "bash",
        &[
            "tools/pil/cargo.sh",
            "clippy",
            "-q",
            "--all-targets",
            "--",
            "-D",
            "warnings",
        ],
    )
}

fn clippy_thumb(ci: &mut Ci) -> Result<(), String> {
    let t = "thumbv7em-none-eabihf";
    ci.run(
        "cargo",
        &[
            "clippy",
            "-p",
            "cfnav",
            "--lib",
            "--bins",
            "--features",
            "firmware",
            "--target",
            t,
            "--",
            "-D",
            "warnings",
        ],
    )?;
    ci.run(
        "cargo",
        &["clippy", "-p", "qemu-bench", "--target", t, "--", "-D", "warnings"],
    )
}

fn test_host(ci: &mut Ci) -> Result<(), String> {
    ci.run("cargo", &["test", "-p", "host-tests"])
}

fn test_tools(ci: &mut Ci) -> Result<(), String> {
    ci.run("cargo", &["test", "-p", "cfnav-tools", "-p", "cfnav-sim"])?;
    ci.run("cargo", &["test", "-p", "xtask"])
}

/// The largest `sub sp, #N` / `sub.w sp, sp, #N` / `subw sp, sp, #N` immediate in a disassembly.
pub fn largest_stack_frame(disassembly: &str) -> Option<u64> {
    let mut best = None;
    for line in disassembly.lines() {
        let mut rest = line;
        while let Some(i) = rest.find("sub") {
            let after = &rest[i + 3..];
            rest = after;
            let after = after
                .strip_prefix(".w")
                .or_else(|| after.strip_prefix('w'))
                .unwrap_or(after);
            let trimmed = after.trim_start();
            if trimmed.len() == after.len() {
                continue; // no whitespace after the mnemonic
            }
            let Some(ops) = trimmed.strip_prefix("sp, ") else {
                continue;
            };
            let ops = ops.strip_prefix("sp, ").unwrap_or(ops);
            let Some(imm) = ops.strip_prefix('#') else { continue };
            let digits: String = imm.chars().take_while(char::is_ascii_digit).collect();
            if let Ok(n) = digits.parse::<u64>() {
                best = best.max(Some(n));
            }
        }
    }
    best
}

/// `(p_vaddr, p_paddr)` of every LOAD segment in `readelf -lW`'s output.
pub fn load_segments(readelf: &str) -> Result<Vec<(u64, u64)>, String> {
    let mut out = Vec::new();
    for line in readelf.lines() {
        let cols: Vec<&str> = line.split_whitespace().collect();
        if cols.first() == Some(&"LOAD") {
            let hex =
                |s: &str| u64::from_str_radix(s.trim_start_matches("0x"), 16).map_err(|e| format!("`{line}`: {e}"));
            let (v, p) = (
                cols.get(2).ok_or("short LOAD line")?,
                cols.get(3).ok_or("short LOAD line")?,
            );
            out.push((hex(v)?, hex(p)?));
        }
    }
    Ok(out)
}

fn firmware(ci: &mut Ci) -> Result<(), String> {
    ci.mkdir("target")?;
    let (flash, ram) = (FLASH_BUDGET_KIB.to_string(), RAM_BUDGET_KIB.to_string());
    ci.cfnav_ok(&[
        "firmware",
        "--out",
        "target/cf2.bin",
        "--max-flash-kib",
        &flash,
        "--max-ram-kib",
        &ram,
    ])?;
    let elf = ci.elf();
    let elf_s = elf.display().to_string();
    ci.run(
        "arm-none-eabi-objcopy",
        &["-O", "binary", &elf_s, "target/cf2-objcopy.bin"],
    )?;
    let ours = fs::read(ci.path("target/cf2.bin")).map_err(|e| format!("target/cf2.bin: {e}"))?;
    let theirs = fs::read(ci.path("target/cf2-objcopy.bin")).map_err(|e| format!("target/cf2-objcopy.bin: {e}"))?;
    ensure(ours == theirs, || "target/cf2.bin differs from objcopy's image".into())?;
    println!("cf2.bin is byte-identical to objcopy's");
    let readelf = ci.output("arm-none-eabi-readelf", &["-lW", &elf_s])?;
    let segments = load_segments(&readelf)?;
    ensure(!segments.is_empty(), || "readelf listed no LOAD segment".into())?;
    for (v, p) in &segments {
        for a in [v, p] {
            ensure(!BOOTLOADER.contains(a), || {
                format!("LOAD segment at {a:#x} lies in the bootloader's sector")
            })?;
        }
    }
    println!("no LOAD segment below {:#x}", BOOTLOADER.end);
    println!("+ arm-none-eabi-objdump -d {elf_s}");
    let dis = ci
        .cmd("arm-none-eabi-objdump", &["-d", &elf_s])
        .output()
        .map_err(|e| format!("arm-none-eabi-objdump: {e}"))?;
    ensure(dis.status.success(), || {
        format!("arm-none-eabi-objdump exited with {}", dis.status)
    })?;
    let frame = largest_stack_frame(&String::from_utf8_lossy(&dis.stdout)).ok_or("no stack frame found")?;
    println!("largest stack frame: {frame} bytes");
    ensure(frame <= STACK_FRAME_BUDGET, || {
        format!("a stack frame of {frame} bytes (> 32 KiB): something large is built on the stack")
    })?;
    // The figures, from the ELF through the same accounting `cfnav firmware` prints.
    let data = fs::read(&elf).map_err(|e| format!("{elf_s}: {e}"))?;
    let layout = read_elf(&data).map_err(|e| format!("{elf_s}: {e:#}"))?;
    let image = build_image(&layout.segments).map_err(|e| format!("{elf_s}: {e:#}"))?;
    ensure(image == ours, || {
        "the image rebuilt from the ELF differs from target/cf2.bin".into()
    })?;
    let usage = MemoryUse::of(image.len(), &layout.sections);
    // ±2 %: a few KiB of new code passes, a dependency or a build mode that grows the image does not; the
    // budgets above stay the hard limits.
    let figures = [
        Figure::within("flash_bytes", usage.flash, 0.02),
        Figure::within("sram_bytes", usage.sram_bytes(), 0.02),
        Figure::within("ccm_bytes", usage.ccm_bytes(), 0.02),
    ];
    expected::check_or_bless(
        &ci.path("ci/expected/firmware.txt"),
        "cfnav firmware's image size and static memory, bytes (each within ±2 %; budgets: flash 288 KiB, SRAM 100 KiB).\n\
         Rewrite with: cargo xtask bless firmware",
        &figures,
        ci.bless,
        "firmware",
    )
}

fn planner(ci: &mut Ci) -> Result<(), String> {
    ci.mkdir("target/plan")?;
    let mut maps: Vec<PathBuf> = fs::read_dir(ci.path("maps"))
        .map_err(|e| format!("maps/: {e}"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "map"))
        .collect();
    maps.sort();
    ensure(!maps.is_empty(), || "no maps/*.map".into())?;
    for map in &maps {
        let name = map.file_stem().unwrap_or_default().to_string_lossy().into_owned();
        let rel = format!("maps/{name}.map");
        let text = fs::read_to_string(map).map_err(|e| format!("{rel}: {e}"))?;
        let want = text
            .lines()
            .find_map(|l| l.strip_prefix("; expect:"))
            .map(str::trim)
            .ok_or_else(|| format!("{rel}: no '; expect:' line"))?
            .to_string();
        let json = format!("target/plan/{name}.json");
        let code = ci.cfnav(&["plan", &rel, "--json", &json])?;
        match want.as_str() {
            "reached" => ensure(code == 0, || {
                format!("{rel}: expected reached (exit 0), got exit {code}")
            })?,
            "no_path" => ensure(code == 1, || {
                format!("{rel}: expected no_path (exit 1), got exit {code}")
            })?,
            other => return Err(format!("{rel}: unknown expectation `{other}`")),
        }
        let report = fs::read_to_string(ci.path(&json)).map_err(|e| format!("{json}: {e}"))?;
        let status = serde_json::from_str::<serde_json::Value>(&report)
            .map_err(|e| format!("{json}: {e}"))?
            .get("status")
            .and_then(|s| s.as_str().map(str::to_string));
        ensure(status.as_deref() == Some(want.as_str()), || {
            format!("{rel}: report status is {status:?}, not {want}")
        })?;
    }
    let code = ci.cfnav(&["plan", "maps/does-not-exist.map"])?;
    ensure(code == 2, || format!("a missing map must exit 2, got {code}"))
}

/// The figures of `tools/qemu-bench/run.sh`'s output that guard regressions, and how each is compared.
/// Instruction counts under `-icount` are exact for one build; ±2 % lets a small change of the code pass
/// while a real regression fails well inside run.sh's own limits. The RAM figure is a static size: exact.
const QEMU_FIGURES: [(&str, Option<f64>); 8] = [
    ("first_plan_instructions", Some(0.02)),
    ("first_plan_and_first_replan_instructions", Some(0.02)),
    ("box_instructions_median", Some(0.02)),
    ("ram_total_bytes", None),
    ("control_step_instructions_max", Some(0.02)),
    ("planner_slice_instructions", Some(0.02)),
    ("map_fix_update_instructions_max", Some(0.02)),
    ("map_fix_cast_instructions_max", Some(0.02)),
];

fn qemu(ci: &mut Ci) -> Result<(), String> {
    // run.sh --check keeps its own limits (exit 1 on a missed target).
    let out = ci.output("bash", &["tools/qemu-bench/run.sh", "--check"])?;
    let value = |key: &str| {
        out.lines()
            .filter_map(|l| l.trim_end_matches('\r').strip_prefix(key)?.strip_prefix('='))
            .next_back()
            .map(str::to_string)
    };
    let mut figures = Vec::new();
    for (key, rule) in QEMU_FIGURES {
        let v = value(key).ok_or_else(|| format!("`{key}=` missing from run.sh's output"))?;
        figures.push(match rule {
            Some(fraction) => Figure::within(key, v, fraction),
            None => Figure::exact(key, v),
        });
    }
    expected::check_or_bless(
        &ci.path("ci/expected/qemu-bench.txt"),
        "Cortex-M4 instruction counts (QEMU mps2-an386, -icount shift=10) and the planner's RAM, from\n\
         tools/qemu-bench/run.sh --check. Counts within ±2 %, RAM exact. Rewrite with: cargo xtask bless qemu",
        &figures,
        ci.bless,
        "qemu",
    )
}

/// A `cfnav sim --json` report of one run, read into the simulator's own type.
fn read_run(path: &Path) -> Result<RunReport, String> {
    let text = fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    // RunReport's names (outcome, reason, mode) are `&'static str`: the text lives as long as CI does.
    let text: &'static str = Box::leak(text.into_boxed_str());
    serde_json::from_str(text).map_err(|e| format!("{}: {e}", path.display()))
}

/// A `cfnav sim --random --json` batch's summary, in the simulator's own type.
fn read_summary(path: &Path) -> Result<Summary, String> {
    let text = fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut value: serde_json::Value = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let summary = value
        .get_mut("summary")
        .map(serde_json::Value::take)
        .ok_or_else(|| format!("{}: no summary", path.display()))?;
    serde_json::from_value(summary).map_err(|e| format!("{}: summary: {e}", path.display()))
}

fn sim_worlds(ci: &mut Ci) -> Result<(), String> {
    ci.mkdir("target/sim")?;
    ci.cfnav_ok(&[
        "sim",
        "--json",
        "target/sim/default.json",
        "--plot",
        "target/sim/default.svg",
    ])?;
    // The built-in world with its own seed: the goal is a completed mission in 60 simulated seconds (the host
    // test checks the median of 120 noise seeds).
    let r = read_run(&ci.path("target/sim/default.json"))?;
    ensure(r.outcome == "completed" && r.collisions == 0, || {
        format!("default world: {} with {} collisions", r.outcome, r.collisions)
    })?;
    let t = r.mission_time_s.unwrap_or(f64::INFINITY);
    ensure(t <= 60.0, || {
        format!("default world: mission time {t} s > 60 s (simulated)")
    })?;
    println!("default world: completed in {t:.1} s");
    let mut worlds: Vec<String> = fs::read_dir(ci.path("worlds"))
        .map_err(|e| format!("worlds/: {e}"))?
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    worlds.sort();
    for name in worlds.iter().filter(|n| n.starts_with("fail-")) {
        let stem = name.trim_end_matches(".toml");
        let (world, json) = (format!("worlds/{name}"), format!("target/sim/{stem}.json"));
        let code = ci.cfnav(&["sim", "--world", &world, "--json", &json])?;
        ensure(code == 1, || {
            format!("{world}: a failure world must end without completing (exit 1), got {code}")
        })?;
        let r = read_run(&ci.path(&json))?;
        ensure(r.reason == Some("no_path") && r.collisions == 0, || {
            format!(
                "{world}: reason {:?}, {} collisions (want no_path, none)",
                r.reason, r.collisions
            )
        })?;
        println!("{}: {} ({}), no collision", r.world, r.outcome, r.reason.unwrap_or("-"));
    }
    // Every other shipped world completes (exit 0); each world file fixes its own noise seed.
    for name in worlds.iter().filter(|n| !n.starts_with("fail-")) {
        let world = format!("worlds/{name}");
        ci.cfnav_ok(&["sim", "--world", &world])
            .map_err(|e| format!("{world} did not complete: {e}"))?;
    }
    Ok(())
}

/// The summary figures an expected file holds: all but the throughput, each exact (the simulator is
/// deterministic per seed, so any change of a figure is a change of the flight). Destructured so a new
/// summary field must be placed here or named as left out.
fn summary_figures(s: &Summary) -> Vec<Figure> {
    let Summary {
        runs,
        completed,
        collisions,
        median_mission_time_s,
        median_landing_error_m,
        p95_landing_error_m,
        completed_fraction,
        sim_seconds_per_wall_second: _,
        large_arena_runs,
        off_pad_landings,
        median_rms_estimate_error_m,
        max_estimate_error_m,
        left_arena_runs,
    } = s;
    let opt = |v: Option<String>| v.unwrap_or_else(|| "none".into());
    vec![
        Figure::exact("runs", runs),
        Figure::exact("completed", completed),
        Figure::exact("collisions", collisions),
        Figure::exact("completed_fraction", format!("{completed_fraction:?}")),
        Figure::exact(
            "median_mission_time_s",
            opt(median_mission_time_s.map(|v| format!("{v:?}"))),
        ),
        Figure::exact(
            "median_landing_error_m",
            opt(median_landing_error_m.map(|v| format!("{v:?}"))),
        ),
        Figure::exact(
            "p95_landing_error_m",
            opt(p95_landing_error_m.map(|v| format!("{v:?}"))),
        ),
        Figure::exact("large_arena_runs", large_arena_runs),
        Figure::exact("off_pad_landings", off_pad_landings),
        Figure::exact("left_arena_runs", left_arena_runs),
        Figure::exact(
            "median_rms_estimate_error_m",
            opt(median_rms_estimate_error_m.map(|v| format!("{v:?}"))),
        ),
        Figure::exact(
            "max_estimate_error_m",
            opt(max_estimate_error_m.map(|v| format!("{v:?}"))),
        ),
    ]
}

/// One CI batch: its arguments, its lower bound on completions and upper bounds on the landing error
/// (median, p95), as measured on these exact batches and rounded to the safe side.
struct Batch {
    name: &'static str,
    args: &'static [&'static str],
    completed_at_least: f64,
    median_at_most_m: f32,
    p95_at_most_m: f32,
}

const BATCHES: [Batch; 3] = [
    // The generator of the first figures (`--generator classic`, seed for seed the same worlds).
    Batch {
        name: "classic-1",
        args: &["--random", "200", "--seed", "1", "--generator", "classic"],
        completed_at_least: 0.98,
        median_at_most_m: 0.03,
        p95_at_most_m: 0.06,
    },
    // The widened generator on a seed never tuned on, default and under worlds/stress.toml.
    Batch {
        name: "wide-100",
        args: &["--random", "200", "--seed", "100"],
        completed_at_least: 0.97,
        median_at_most_m: 0.026,
        p95_at_most_m: 0.056,
    },
    Batch {
        name: "wide-100-stress",
        args: &["--random", "200", "--seed", "100", "--stress", "worlds/stress.toml"],
        completed_at_least: 0.875,
        median_at_most_m: 0.038,
        p95_at_most_m: 0.080,
    },
];

fn sim_batches(ci: &mut Ci) -> Result<(), String> {
    ci.mkdir("target/sim")?;
    for b in &BATCHES {
        let json = format!("target/sim/{}.json", b.name);
        let mut args = vec!["sim"];
        args.extend_from_slice(b.args);
        args.extend_from_slice(&["--json", &json]);
        ci.cfnav_ok(&args)?;
        let s = read_summary(&ci.path(&json))?;
        println!("{}: {s:?}", b.name);
        println!(
            "simulated seconds per wall second: {:.0} (printed, not judged)",
            s.sim_seconds_per_wall_second
        );
        let median = s.median_landing_error_m.unwrap_or(f32::INFINITY);
        let p95 = s.p95_landing_error_m.unwrap_or(f32::INFINITY);
        ensure(s.runs == 200, || format!("{}: {} runs, not 200", b.name, s.runs))?;
        ensure(s.collisions == 0, || format!("{}: {} collisions", b.name, s.collisions))?;
        ensure(s.completed_fraction >= b.completed_at_least, || {
            format!(
                "{}: completed {} < {}",
                b.name, s.completed_fraction, b.completed_at_least
            )
        })?;
        ensure(median <= b.median_at_most_m, || {
            format!("{}: median landing error {median} m > {} m", b.name, b.median_at_most_m)
        })?;
        ensure(p95 <= b.p95_at_most_m, || {
            format!("{}: p95 landing error {p95} m > {} m", b.name, b.p95_at_most_m)
        })?;
        expected::check_or_bless(
            &ci.path(&format!("ci/expected/sim-{}.txt", b.name)),
            &format!(
                "The summary of `cfnav sim {}` (exact: the simulator is deterministic per seed;\n\
                 the throughput is left out). Rewrite with: cargo xtask bless sim-batches",
                b.args.join(" ")
            ),
            &summary_figures(&s),
            ci.bless,
            "sim-batches",
        )?;
    }
    Ok(())
}

fn readme_step(ci: &mut Ci) -> Result<(), String> {
    let text = fs::read_to_string(ci.path("README.md")).map_err(|e| format!("README.md: {e}"))?;
    let lines = readme::sh_lines(&text);
    ensure(!lines.is_empty(), || "README.md has no ```sh block".into())?;
    let already = ci.passed.borrow().clone();
    let ran = readme::run("README.md", &lines, &ci.root, &already)?;
    println!("README.md: {ran} command lines ran, all exited 0");
    Ok(())
}

fn cfclient(ci: &mut Ci) -> Result<(), String> {
    // Runs alone, before the emulator queue starts: beside the queue's two workers a harness stalled for
    // 3 s or more made the drone drop the silent link's log blocks and cfclient's Flight tab froze.
    ci.run("cargo", &["build", "-q", "--release", "-p", "cfnav-tools"])?;
    ci.run("timeout", &["180", "bash", "tools/e2e/cfclient.sh"])
        .map_err(|e| format!("the stock cfclient/cflib check failed or took over 3 min: {e}"))
}

/// The emulator's background runs: name, arguments after the program, the check applied (`--check`).
/// Longest first, so the two workers end close together. The hover-mode fault runs end at their own
/// --seconds where nothing is left to see.
const PIL_JOBS: [(&str, &str, Option<&str>); 14] = [
    ("hover", "--hover 10 --seed 1", Some("hover")),
    (
        "flow-lost",
        "--hover 1 --seed 2 --fault flow-deck-lost:4.5",
        Some("flow-lost"),
    ),
    (
        "mr-lost",
        "--hover 1 --seed 2 --fault multiranger-lost:4.5",
        Some("mr-lost"),
    ),
    ("client", "--client toc --seconds 8", Some("client")),
    (
        "imu-lost",
        "--hover 1 --seed 2 --fault imu-lost:4.5 --seconds 7",
        Some("imu-lost"),
    ),
    (
        "no-multiranger",
        "--no-multiranger --hover 1 --seconds 6",
        Some("no-multiranger"),
    ),
    (
        "dead",
        "--fault sensor-bus-dead --expect fault --no-stop --seconds 3",
        Some("dead"),
    ),
    (
        "stuck-never",
        "--fault sensor-bus-stuck:never --fault deck-bus-stuck:never --expect fault --no-stop --seconds 3",
        Some("stuck-never"),
    ),
    ("rts", "--fault rts-high --no-stop --seconds 3", Some("rts")),
    (
        "tx-dead",
        "--fault syslink-tx-dead --no-stop --seconds 3",
        Some("tx-dead"),
    ),
    ("boot1", "", Some("boot")),
    // The same boot through `cfnav pil` (it finds cfnav-pil in the same target directory): compared with
    // boot1 by `--same-boot` once both are done.
    ("boot2", "", None),
    ("nack", "--fault bmi088-reset-nack", Some("nack")),
    (
        "stuck",
        "--fault sensor-bus-stuck --fault deck-bus-stuck",
        Some("stuck"),
    ),
];

/// The order the emulator's results are judged in (the unmodified-cflib run first, as it ran first).
const PIL_ORDER: [&str; 15] = [
    "cflib",
    "boot1",
    "boot2",
    "nack",
    "dead",
    "stuck",
    "stuck-never",
    "rts",
    "tx-dead",
    "client",
    "hover",
    "flow-lost",
    "imu-lost",
    "mr-lost",
    "no-multiranger",
];

fn pil(ci: &mut Ci) -> Result<(), String> {
    ci.run("bash", &["tools/pil/cargo.sh", "build", "-q"])?;
    // The device models, and the core's ITSTATE across an exception (the rsemu fix in tools/pil/patches/).
    ci.run("bash", &["tools/pil/cargo.sh", "test", "-q"])?;
    ci.run("python3", &["-m", "pip", "install", "-q", "cflib>=0.1.32"])?;
    let pil = ci.target.join("debug/cfnav-pil").display().to_string();
    let cfnav = ci.release_cfnav();
    let elf = ci.elf().display().to_string();
    let queue = ci.path("target/pil/queue");
    let _ = fs::remove_dir_all(&queue);
    ci.mkdir("target/pil/queue")?;
    // Unmodified cflib over UDP runs first and alone: its wall-clock pacing meets the emulator's virtual
    // time, and beside the queue's workers one request of its connect once went unanswered and cflib, which
    // never retries over UDP, waited out its timeout. Its result is judged with the others.
    let started = Instant::now();
    let log = fs::File::create(queue.join("cflib.log")).map_err(|e| format!("cflib.log: {e}"))?;
    let err = log.try_clone().map_err(|e| format!("cflib.log: {e}"))?;
    let args = [
        "900",
        "python3",
        "tools/e2e/cflib_pil.py",
        "--pil",
        &pil,
        "--elf",
        &elf,
        "--port",
        "19860",
        "--timeout",
        "800",
        "--json",
        "target/pil/cflib.json",
    ];
    println!("+ timeout {} > target/pil/queue/cflib.log", args.join(" "));
    let status = ci
        .cmd("timeout", &args)
        .stdout(log)
        .stderr(err)
        .status()
        .map_err(|e| format!("cflib_pil.py: {e}"))?;
    let write = |name: &str, text: String| fs::write(queue.join(name), text).map_err(|e| format!("{name}: {e}"));
    write("cflib.wall", format!("{}\n", started.elapsed().as_secs()))?;
    write("cflib.rc", format!("{}\n", status.code().unwrap_or(1)))?;
    let mut jobs = String::new();
    for (name, args, check) in PIL_JOBS {
        let program = if name == "boot2" {
            format!("{cfnav} pil")
        } else {
            pil.clone()
        };
        let check = check.map(|c| format!(" --check {c}")).unwrap_or_default();
        jobs += &format!("{name} {program} --elf {elf} {args} --json target/pil/{name}.json{check}\n");
    }
    fs::write(ci.path("target/pil/jobs"), &jobs).map_err(|e| format!("target/pil/jobs: {e}"))?;
    let queue_log = fs::File::create(ci.path("target/pil/queue.log")).map_err(|e| format!("queue.log: {e}"))?;
    let queue_err = queue_log.try_clone().map_err(|e| format!("queue.log: {e}"))?;
    use std::os::unix::process::CommandExt;
    println!("+ bash tools/pil/queue.sh target/pil/jobs target/pil/queue 2 &");
    let child = ci
        .cmd(
            "bash",
            &["tools/pil/queue.sh", "target/pil/jobs", "target/pil/queue", "2"],
        )
        .stdout(queue_log)
        .stderr(queue_err)
        .process_group(0)
        .spawn()
        .map_err(|e| format!("queue.sh: {e}"))?;
    let id = child.id();
    ci.background.push(child);
    let queue_started = Instant::now();
    ci.deferred.push((
        "pil-results",
        "the emulator's runs, each judged by its check (cfnav-pil --check NAME)",
        Box::new(move |ci: &mut Ci| pil_results(ci, id, queue_started)),
    ));
    Ok(())
}

/// Waits for the queued run `name`, prints its output; `Err` unless it exited 0.
fn pil_wait(ci: &mut Ci, queue_id: u32, name: &str) -> Result<(), String> {
    let dir = ci.path("target/pil/queue");
    let rc = dir.join(format!("{name}.rc"));
    let waited = Instant::now();
    while !rc.exists() {
        let alive = ci
            .background
            .iter_mut()
            .find(|c| c.id() == queue_id)
            .is_some_and(|c| matches!(c.try_wait(), Ok(None)));
        if !alive && !rc.exists() {
            let log = fs::read_to_string(ci.path("target/pil/queue.log")).unwrap_or_default();
            return Err(format!("the emulator queue ended without finishing {name}:\n{log}"));
        }
        if waited.elapsed() > Duration::from_secs(3600) {
            return Err(format!("{name}: no result after an hour"));
        }
        std::thread::sleep(Duration::from_secs(2));
    }
    let read = |ext: &str| fs::read_to_string(dir.join(format!("{name}.{ext}"))).unwrap_or_default();
    print!("{}", read("log"));
    println!(
        "[{name}: {} s of wall time in the background queue]",
        read("wall").trim()
    );
    match read("rc").trim() {
        "0" => Ok(()),
        rc => Err(format!("{name} exited {rc}")),
    }
}

fn pil_results(ci: &mut Ci, queue_id: u32, started: Instant) -> Result<(), String> {
    let mut failed = Vec::new();
    for name in PIL_ORDER {
        println!("\n--- pil: {name}");
        if let Err(e) = pil_wait(ci, queue_id, name) {
            println!("FAILED {name}: {e}");
            failed.push(name);
        }
        if name == "boot2" {
            let pil = ci.target.join("debug/cfnav-pil").display().to_string();
            let same = ci.run(&pil, &["--same-boot", "target/pil/boot1.json", "target/pil/boot2.json"]);
            if let Err(e) = same {
                println!("FAILED boot1 = boot2: {e}");
                failed.push("boot1 = boot2");
            }
        }
    }
    println!(
        "the emulator queue took {} s of wall time from its start",
        started.elapsed().as_secs()
    );
    // The default world's round trip on the image vs SITL: ≈ 20 min of wall time per seed, over what this
    // CI may add, so opt-in (`CFNAV_NIGHTLY=1`, seeds from CFNAV_NIGHTLY_SEEDS, default "1 2").
    if std::env::var("CFNAV_NIGHTLY").as_deref() == Ok("1") {
        let seeds = std::env::var("CFNAV_NIGHTLY_SEEDS").unwrap_or_else(|_| "1 2".into());
        let mut args = vec!["tools/pil/nightly.sh"];
        args.extend(seeds.split_whitespace());
        if let Err(e) = ci.run("bash", &args) {
            println!("FAILED nightly: {e}");
            failed.push("nightly");
        }
    }
    ci.stop(queue_id);
    ensure(failed.is_empty(), || format!("failed: {}", failed.join(", ")))
}

fn fuzz(ci: &mut Ci) -> Result<(), String> {
    // Only stable Rust is installed: cargo-fuzz passes nightly-only flags, which RUSTC_BOOTSTRAP=1 allows.
    // No sanitizer (-s none): the library has no unsafe code; coverage guidance and Rust's panics (the
    // targets' own assertions included) are what the run checks. A crash leaves its input in
    // fuzz/artifacts/<target>/.
    if !ci
        .cmd("cargo", &["fuzz", "--version"])
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
    {
        ci.run("cargo", &["install", "-q", "cargo-fuzz", "--locked"])?;
    }
    let fuzz_dir = ci.path("fuzz");
    let cargo_fuzz = |args: &[&str]| {
        let mut c = ci.cmd("cargo", &["fuzz"]);
        c.args(args).current_dir(&fuzz_dir).env("RUSTC_BOOTSTRAP", "1");
        c
    };
    println!("+ (cd fuzz && cargo fuzz build -s none)");
    let s = cargo_fuzz(&["build", "-s", "none"])
        .status()
        .map_err(|e| format!("cargo fuzz: {e}"))?;
    ensure(s.success(), || format!("cargo fuzz build exited with {s}"))?;
    for target in ["syslink_decode", "crtp_router", "param_log_services"] {
        println!("+ (cd fuzz && cargo fuzz run -s none {target} -- -max_total_time=20)");
        // libFuzzer logs every new coverage point: the log is shown only when the run fails.
        let out = cargo_fuzz(&["run", "-s", "none", target, "--", "-max_total_time=20"])
            .output()
            .map_err(|e| format!("cargo fuzz: {e}"))?;
        let log = String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout);
        if !out.status.success() {
            let lines: Vec<&str> = log.lines().collect();
            println!("{}", lines[lines.len().saturating_sub(60)..].join("\n"));
            return Err(format!("fuzz target {target} failed ({})", out.status));
        }
        let done = log.lines().find(|l| l.starts_with("Done")).unwrap_or("-");
        println!("{target}: {done}");
    }
    Ok(())
}

/// Starts `cfnav sim --serve --port PORT --speed SPEED` and waits until it answers cflib's scan probe.
fn serve(ci: &mut Ci, port: u16, speed: &str) -> Result<u32, String> {
    ci.run("cargo", &["build", "-q", "--release", "-p", "cfnav-tools"])?;
    let cfnav = ci.release_cfnav();
    let port_s = port.to_string();
    let id = ci.spawn(&cfnav, &["sim", "--serve", "--port", &port_s, "--speed", speed])?;
    if readme::answers_scan_probe(port, Duration::from_secs(60)) {
        Ok(id)
    } else {
        ci.stop(id);
        Err(format!("the simulator does not answer on udp://127.0.0.1:{port}"))
    }
}

fn e2e_cflib(ci: &mut Ci) -> Result<(), String> {
    // Unmodified cflib sets the goal, sees a bad goal refused, logs and flies the mission. The protocol part
    // must pass every time; the flight completes about nine times in ten on generated worlds and its noise
    // depends on when the start packet arrives, so a flight that ends without completing gets one more
    // mission on the same server before the step fails.
    let id = serve(ci, 19850, "20")?;
    ci.run("python3", &["-m", "pip", "install", "-q", "cflib>=0.1.32"])?;
    let args = [
        "180",
        "python3",
        "tools/e2e/cflib_mission.py",
        "--uri",
        "udp://127.0.0.1:19850",
        "--timeout",
        "150",
    ];
    let mut r = ci.run("timeout", &args);
    if r.is_err() {
        println!("the first mission over cflib did not complete; flying a second one");
        r = ci.run("timeout", &args);
    }
    ci.stop(id);
    r
}

fn e2e_mission_start(ci: &mut Ci) -> Result<(), String> {
    // A fresh simulator per case on port 19851: refused goal (exit 2), a completed flight (exit 0, state 100;
    // one more if the first does not complete), Ctrl-C (exit 130), no simulator (exit 2).
    let mut c = ci.cmd("bash", &["tools/e2e/mission_start.sh"]);
    c.env("PORT", "19851");
    println!("+ PORT=19851 bash tools/e2e/mission_start.sh");
    let s = c.status().map_err(|e| format!("mission_start.sh: {e}"))?;
    ensure(s.success(), || format!("tools/e2e/mission_start.sh exited with {s}"))
}

fn e2e_high_level(ci: &mut Ci) -> Result<(), String> {
    // Real time: take-off, relative smooth go_to, absolute linear go_to, land, stop; the logged
    // stateEstimate must reach each target.
    let id = serve(ci, 19852, "1")?;
    let r = ci.run(
        "timeout",
        &[
            "120",
            "python3",
            "tools/e2e/cflib_high_level.py",
            "--uri",
            "udp://127.0.0.1:19852",
            "--timeout",
            "100",
        ],
    );
    ci.stop(id);
    r
}

fn e2e_persistent(ci: &mut Ci) -> Result<(), String> {
    // The script restarts its simulator (with an EEPROM file) twice as a power cycle.
    let cfnav = ci.release_cfnav();
    ci.run("cargo", &["build", "-q", "--release", "-p", "cfnav-tools"])?;
    ci.run(
        "timeout",
        &[
            "180",
            "python3",
            "tools/e2e/cflib_persistent.py",
            "--sim",
            &cfnav,
            "--port",
            "19853",
        ],
    )
}

fn e2e_sequence(ci: &mut Ci) -> Result<(), String> {
    // One connection, what a user does in turn: HighLevelCommander and MotionCommander flights, then the
    // hover test (it must land at its take-off point, state 100, only hover states seen); a round trip
    // started off the home pad is refused, then flown from the pad. The script starts its own simulator.
    let cfnav = ci.release_cfnav();
    ci.run("cargo", &["build", "-q", "--release", "-p", "cfnav-tools"])?;
    ci.run(
        "timeout",
        &[
            "300",
            "python3",
            "tools/e2e/cflib_sequence.py",
            "--sim",
            &cfnav,
            "--port",
            "19858",
            "--out",
            "target/e2e-sequence",
        ],
    )
}

fn e2e_motion(ci: &mut Ci) -> Result<(), String> {
    let id = serve(ci, 19854, "1")?;
    let r = ci.run(
        "timeout",
        &[
            "150",
            "python3",
            "tools/e2e/cflib_motion.py",
            "--uri",
            "udp://127.0.0.1:19854",
            "--timeout",
            "130",
        ],
    );
    ci.stop(id);
    r
}

fn e2e_setpoint_modes(ci: &mut Ci) -> Result<(), String> {
    // The scripts start fresh simulators themselves (ports 19857 and 19856).
    ci.run("cargo", &["build", "-q", "--release", "-p", "cfnav-tools"])?;
    let cfnav = ci.release_cfnav();
    ci.run(
        "timeout",
        &[
            "60",
            "python3",
            "tools/e2e/cflib_setpoint.py",
            "--sim",
            &cfnav,
            "--port",
            "19857",
            "--out",
            "target/e2e-setpoint",
            "--timeout",
            "55",
        ],
    )?;
    ci.run(
        "timeout",
        &[
            "120",
            "python3",
            "tools/e2e/cflib_modes.py",
            "--sim",
            &cfnav,
            "--port",
            "19856",
            "--out",
            "target/e2e-modes",
            "--timeout",
            "115",
        ],
    )
}

fn e2e_map(ci: &mut Ci) -> Result<(), String> {
    ci.run("cargo", &["build", "-q", "--release", "-p", "cfnav-tools"])?;
    let mut c = ci.cmd("timeout", &["240", "bash", "tools/e2e/map_pc.sh"]);
    c.env("PORT", "19855");
    println!("+ PORT=19855 timeout 240 bash tools/e2e/map_pc.sh");
    let s = c.status().map_err(|e| format!("map_pc.sh: {e}"))?;
    ensure(s.success(), || {
        format!("the map-on-the-PC check failed or took over 4 min ({s})")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_stack_frame_is_found_in_each_encoding() {
        let dis = " 8004000:\tb08e      \tsub\tsp, #56\n\
                   \x20800400a:\tf5ad 5d80 \tsub.w\tsp, sp, #4096\n\
                   \x208004010:\tf2ad 4d04 \tsubw\tsp, sp, #1028\n\
                   \x208004014:\tee30 0a41 \tvsub.f32\ts0, s0, s2\n\
                   \x208004018:\t1a40      \tsubs\tr0, r0, r1\n\
                   \x20800401a:\tb082      \tsub\tsp, #8\n";
        assert_eq!(largest_stack_frame(dis), Some(4096));
        assert_eq!(largest_stack_frame("\tsubs\tr0, #9999\n"), None);
    }

    #[test]
    fn load_segments_are_read_from_readelf() {
        let text = "Program Headers:\n\
            \x20 Type           Offset   VirtAddr   PhysAddr   FileSiz MemSiz  Flg Align\n\
            \x20 LOAD           0x0000f4 0x08004000 0x08004000 0x00188 0x00188 R   0x4\n\
            \x20 LOAD           0x04c8a0 0x20000000 0x0804c7a0 0x00038 0x00038 RW  0x10\n";
        assert_eq!(
            load_segments(text).unwrap(),
            vec![(0x0800_4000, 0x0800_4000), (0x2000_0000, 0x0804_c7a0)]
        );
    }

    #[test]
    fn step_names_are_unique_and_blessable_steps_exist() {
        for (i, s) in STEPS.iter().enumerate() {
            assert!(STEPS[i + 1..].iter().all(|t| t.name != s.name), "{} twice", s.name);
        }
        for b in BLESSABLE {
            assert!(STEPS.iter().any(|s| s.name == b), "{b}");
        }
        for (name, _, _) in PIL_JOBS {
            assert!(PIL_ORDER.contains(&name), "{name} is run but never judged");
        }
    }

    #[test]
    fn summary_figures_leave_out_only_the_throughput() {
        let s = Summary {
            runs: 200,
            completed: 196,
            collisions: 0,
            median_mission_time_s: Some(61.25),
            median_landing_error_m: Some(0.0252),
            p95_landing_error_m: None,
            completed_fraction: 0.98,
            sim_seconds_per_wall_second: 272.8,
            large_arena_runs: 3,
            off_pad_landings: 1,
            median_rms_estimate_error_m: Some(0.01),
            max_estimate_error_m: Some(0.2),
            left_arena_runs: 0,
        };
        let figures = summary_figures(&s);
        assert_eq!(figures.len(), 12);
        assert!(figures.iter().all(|f| f.rule == expected::Rule::Exact));
        assert!(!figures.iter().any(|f| f.key.contains("wall")));
        let text = expected::render("h", &figures);
        assert!(text.contains("median_landing_error_m 0.0252\n") && text.contains("p95_landing_error_m none\n"));
        let faster = Summary {
            sim_seconds_per_wall_second: 1.0,
            ..s
        };
        assert!(expected::compare(&text, &summary_figures(&faster)).unwrap().is_empty());
    }
}
