//! `cfnav firmware`: builds the release firmware for the Crazyflie 2.1 and writes the raw image that the radio
//! bootloader flashes (`cfloader flash cf2.bin stm32-fw`), then reports flash, SRAM and CCM use.
//!
//! The image holds the bytes of every ELF `PT_LOAD` segment with file contents, placed at its physical (load)
//! address, alignment gaps filled with 0x00, starting exactly at the application start 0x0800_4000: the same
//! bytes as `arm-none-eabi-objcopy -O binary` (CI compares the two). The image is refused if any
//! byte would land outside the application flash or the vector table looks wrong.
//!
//! The ELF → image conversion and the size accounting are pure functions, tested below.
use std::env;
use std::ffi::OsString;
use std::fs;
use std::io::{BufRead, BufReader};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};

use anyhow::{Context, Result, anyhow, bail, ensure};
use object::elf;
use object::read::elf::{FileHeader, ProgramHeader, SectionHeader};

/// Where the application (and its vector table) starts: the radio bootloader owns flash sector 0 below it.
pub const APP_FLASH_START: u32 = 0x0800_4000;
/// Application flash: 1024 KiB minus the bootloader's 16 KiB.
pub const APP_FLASH_SIZE: u32 = 1008 * 1024;
/// SRAM1 + SRAM2, contiguous (128 KiB).
pub const SRAM: Range<u32> = 0x2000_0000..0x2002_0000;
/// Core-coupled RAM (64 KiB), CPU-only.
pub const CCM: Range<u32> = 0x1000_0000..0x1001_0000;
/// What fills the image between segments (alignment gaps): 0x00, as `objcopy -O binary` does, which is
/// how the stock Crazyflie build makes its `cf2.bin`; the image is then byte-identical to objcopy's.
pub const GAP_FILL: u8 = 0x00;

const TARGET_TRIPLE: &str = "thumbv7em-none-eabihf";
const BIN_NAME: &str = "firmware";
const IMAGE_NAME: &str = "cf2.bin";

/// Options of `cfnav firmware`.
#[derive(clap::Args, Debug)]
pub struct FirmwareArgs {
    /// Where to write the raw image [default: cf2.bin in the workspace's target directory]
    #[arg(long, value_name = "PATH")]
    pub out: Option<PathBuf>,
    /// Fail (exit 1) if the image is larger than this many KiB of flash [default: the chip's 1008 KiB
    /// application region]; CI passes a tighter regression budget
    #[arg(long, value_name = "N", default_value_t = APP_FLASH_SIZE / 1024)]
    pub max_flash_kib: u32,
    /// Fail (exit 1) if static SRAM use (.data, .bss, .uninit, …; not the stack) exceeds this many KiB
    /// [default: the chip's 128 KiB of SRAM]; CI passes a tighter regression budget
    #[arg(long, value_name = "N", default_value_t = (SRAM.end - SRAM.start) / 1024)]
    pub max_ram_kib: u32,
}

/// The command that installs the firmware's compilation target (printed verbatim when it is missing).
pub const ADD_TARGET_COMMAND: &str = "rustup target add thumbv7em-none-eabihf";

/// Runs `cfnav firmware`: exit 0 when the image was built and written, 2 at once when the thumb target is
/// missing and cannot be added (with the command that adds it), 1 otherwise (with a one-line reason).
pub fn run(args: &FirmwareArgs) -> ExitCode {
    if let Err(message) = ensure_target(&workspace_root()) {
        eprintln!("error: {message}");
        return ExitCode::from(2);
    }
    match build_and_write(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
    }
}

fn build_and_write(args: &FirmwareArgs) -> Result<()> {
    let root = workspace_root();
    let elf_path = cargo_build_firmware(&root)?;
    let data = fs::read(&elf_path).with_context(|| format!("cannot read the firmware ELF {}", elf_path.display()))?;
    let layout = read_elf(&data).with_context(|| format!("bad firmware ELF {}", elf_path.display()))?;
    let image = build_image(&layout.segments).with_context(|| format!("bad firmware ELF {}", elf_path.display()))?;
    check_vector_table(&image).with_context(|| format!("bad firmware ELF {}", elf_path.display()))?;
    let usage = MemoryUse::of(image.len(), &layout.sections);

    let out = match &args.out {
        Some(out) => out.clone(),
        None => target_dir(&root, &elf_path)?.join(IMAGE_NAME),
    };
    print!("{}", usage.report());
    check_budgets(&usage, args.max_flash_kib, args.max_ram_kib)?;
    fs::write(&out, &image).with_context(|| format!("cannot write the image {}", out.display()))?;
    println!(
        "wrote {} ({} bytes from 0x{APP_FLASH_START:08x})",
        out.display(),
        image.len()
    );
    Ok(())
}

/// Whether the standard library of [`TARGET_TRIPLE`] is in the toolchain whose sysroot is `sysroot`: its
/// `lib/rustlib/<triple>/lib` holds a `libcore-*.rlib`. Without it cargo fails deep in the build with
/// "can't find crate for `core`".
pub fn target_installed(sysroot: &Path) -> bool {
    let lib = sysroot.join("lib").join("rustlib").join(TARGET_TRIPLE).join("lib");
    fs::read_dir(lib).is_ok_and(|entries| {
        entries.flatten().any(|e| {
            let name = e.file_name();
            let name = name.to_string_lossy();
            name.starts_with("libcore-") && name.ends_with(".rlib")
        })
    })
}

/// What to do about the thumb target before building.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TargetPlan {
    /// The target is installed: build.
    Build,
    /// Missing, rustup is there: run [`ADD_TARGET_COMMAND`] (saying so), then build.
    AddWithRustup,
    /// Missing and no rustup (or the sysroot is unknown): stop with [`ADD_TARGET_COMMAND`], exit 2.
    Stop,
}

/// The decision of [`ensure_target`], from what was found (pure, for the tests).
pub fn target_plan(sysroot: Option<&Path>, rustup_available: bool) -> TargetPlan {
    match sysroot {
        Some(root) if target_installed(root) => TargetPlan::Build,
        _ if rustup_available => TargetPlan::AddWithRustup,
        _ => TargetPlan::Stop,
    }
}

/// The message printed when the target is missing and could not be added.
pub fn missing_target_message(detail: &str) -> String {
    format!("the Rust target {TARGET_TRIPLE} is not installed ({detail}); install it with:\n    {ADD_TARGET_COMMAND}")
}

/// The sysroot of the toolchain cargo will use in `root` (rustup resolves `rust-toolchain.toml` there).
fn sysroot(root: &Path) -> Option<PathBuf> {
    let rustc = env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    let out = Command::new(rustc)
        .current_dir(root)
        .args(["--print", "sysroot"])
        .stdin(Stdio::null())
        .stderr(Stdio::null())
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8(out.stdout).ok()?;
    let path = PathBuf::from(text.trim());
    path.is_dir().then_some(path)
}

fn rustup_available(root: &Path) -> bool {
    Command::new("rustup")
        .current_dir(root)
        .arg("--version")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Makes sure the thumb target is installed before the build: adds it with rustup (saying so on stderr),
/// or returns the message that names [`ADD_TARGET_COMMAND`].
fn ensure_target(root: &Path) -> Result<(), String> {
    let sysroot = sysroot(root);
    match target_plan(sysroot.as_deref(), rustup_available(root)) {
        TargetPlan::Build => Ok(()),
        TargetPlan::Stop => Err(missing_target_message("and rustup is not available to add it")),
        TargetPlan::AddWithRustup => {
            eprintln!("the Rust target {TARGET_TRIPLE} is missing; adding it: {ADD_TARGET_COMMAND}");
            let status = Command::new("rustup")
                .current_dir(root)
                .args(["target", "add", TARGET_TRIPLE])
                .stdin(Stdio::null())
                .status();
            match status {
                Ok(s) if s.success() => Ok(()),
                Ok(s) => Err(missing_target_message(&format!("rustup failed: {s}"))),
                Err(e) => Err(missing_target_message(&format!("cannot run rustup: {e}"))),
            }
        }
    }
}

/// The workspace root: the parent of this package's folder (`tools/`).
fn workspace_root() -> PathBuf {
    let tools = Path::new(env!("CARGO_MANIFEST_DIR"));
    tools.parent().unwrap_or(tools).to_path_buf()
}

/// The cargo that runs us (`$CARGO`), else the one on the PATH.
fn cargo() -> OsString {
    env::var_os("CARGO").unwrap_or_else(|| "cargo".into())
}

/// Builds the firmware in release mode and returns the path of its ELF, as cargo reports it (so
/// `CARGO_TARGET_DIR` and `build.target-dir` are respected). Cargo's diagnostics go to our stderr.
fn cargo_build_firmware(root: &Path) -> Result<PathBuf> {
    let cargo = cargo();
    let mut child = Command::new(&cargo)
        .current_dir(root)
        .args([
            "build",
            "--release",
            "-p",
            "cfnav",
            "--bin",
            BIN_NAME,
            "--features",
            "firmware",
            "--target",
            TARGET_TRIPLE,
        ])
        .arg("--message-format=json-render-diagnostics")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .with_context(|| format!("cannot run {}", Path::new(&cargo).display()))?;
    let stdout = child
        .stdout
        .take()
        .ok_or_else(|| anyhow!("cannot read cargo's output"))?;
    let mut elf = None;
    for line in BufReader::new(stdout).lines() {
        let line = line.context("cannot read cargo's output")?;
        if let Some(path) = firmware_artifact(&line) {
            elf = Some(path);
        }
    }
    let status = child.wait().context("cannot wait for cargo")?;
    ensure!(status.success(), "cargo build of the firmware failed ({status})");
    elf.ok_or_else(|| anyhow!("cargo built the firmware but reported no executable for the `{BIN_NAME}` binary"))
}

/// The executable of the firmware binary, if `line` is cargo's `compiler-artifact` message for it.
fn firmware_artifact(line: &str) -> Option<PathBuf> {
    let msg: serde_json::Value = serde_json::from_str(line).ok()?;
    if msg.get("reason")?.as_str()? != "compiler-artifact" {
        return None;
    }
    let target = msg.get("target")?;
    let is_bin = target
        .get("kind")?
        .as_array()?
        .iter()
        .any(|k| k.as_str() == Some("bin"));
    if !is_bin || target.get("name")?.as_str()? != BIN_NAME {
        return None;
    }
    msg.get("executable")?.as_str().map(PathBuf::from)
}

/// The workspace's target directory: cargo metadata's `target_directory`, else derived from the ELF's path.
fn target_dir(root: &Path, elf: &Path) -> Result<PathBuf> {
    let from_metadata = Command::new(cargo())
        .current_dir(root)
        .args(["metadata", "--format-version", "1", "--no-deps"])
        .stdin(Stdio::null())
        .stderr(Stdio::null())
        .output()
        .ok()
        .filter(|out| out.status.success())
        .and_then(|out| serde_json::from_slice::<serde_json::Value>(&out.stdout).ok())
        .and_then(|meta| meta.get("target_directory")?.as_str().map(PathBuf::from));
    from_metadata
        .or_else(|| target_dir_from_artifact(elf))
        .ok_or_else(|| anyhow!("cannot find the target directory of {}; give --out", elf.display()))
}

/// `<target dir>/thumbv7em-none-eabihf/release/firmware` → `<target dir>`.
fn target_dir_from_artifact(elf: &Path) -> Option<PathBuf> {
    let release = elf.parent()?;
    let triple = release.parent()?;
    if release.file_name()? != "release" || triple.file_name()? != TARGET_TRIPLE {
        return None;
    }
    triple.parent().map(Path::to_path_buf)
}

/// A `PT_LOAD` segment's file contents and where they are loaded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadSegment<'a> {
    /// Physical (load) address: where the bytes sit in flash.
    pub paddr: u32,
    /// The bytes (`p_filesz` of them).
    pub data: &'a [u8],
}

/// An allocated (`SHF_ALLOC`) section: it occupies memory at run time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AllocSection {
    /// Section name, e.g. `.bss`.
    pub name: String,
    /// Run-time (virtual) address.
    pub addr: u32,
    /// Size in bytes.
    pub size: u32,
}

/// What the image and the accounting need from the ELF.
#[derive(Debug)]
pub struct ElfLayout<'a> {
    /// Every `PT_LOAD` segment, in file order (including those with no file contents).
    pub segments: Vec<LoadSegment<'a>>,
    /// Every allocated section with a non-zero size.
    pub sections: Vec<AllocSection>,
}

/// Reads the load segments and allocated sections of a 32-bit little-endian ARM ELF.
pub fn read_elf(data: &[u8]) -> Result<ElfLayout<'_>> {
    let header = elf::FileHeader32::<object::LittleEndian>::parse(data)
        .map_err(|e| anyhow!("not a 32-bit little-endian ELF file: {e}"))?;
    let endian = header
        .endian()
        .map_err(|e| anyhow!("not a little-endian ELF file: {e}"))?;
    let machine = header.e_machine(endian);
    ensure!(
        machine == elf::EM_ARM,
        "ELF machine is {machine}, not ARM ({})",
        elf::EM_ARM
    );

    let mut segments = Vec::new();
    for ph in header
        .program_headers(endian, data)
        .map_err(|e| anyhow!("bad program headers: {e}"))?
    {
        if ph.p_type(endian) != elf::PT_LOAD {
            continue;
        }
        let paddr = ph.p_paddr(endian);
        let bytes = ph
            .data(endian, data)
            .map_err(|()| anyhow!("LOAD segment at 0x{paddr:08x} lies outside the file"))?;
        segments.push(LoadSegment { paddr, data: bytes });
    }

    let table = header
        .sections(endian, data)
        .map_err(|e| anyhow!("bad section headers: {e}"))?;
    let mut sections = Vec::new();
    for sh in table.iter() {
        let size = sh.sh_size(endian);
        if sh.sh_flags(endian) & elf::SHF_ALLOC == 0 || size == 0 {
            continue;
        }
        let name = table
            .section_name(endian, sh)
            .map_err(|e| anyhow!("bad section name: {e}"))?;
        sections.push(AllocSection {
            name: String::from_utf8_lossy(name).into_owned(),
            addr: sh.sh_addr(endian),
            size,
        });
    }
    Ok(ElfLayout { segments, sections })
}

/// The raw image: the file bytes of the load segments at their physical addresses, from [`APP_FLASH_START`],
/// gaps [`GAP_FILL`]. Refuses bytes outside the application flash, overlapping segments and an image with nothing in it.
pub fn build_image(segments: &[LoadSegment<'_>]) -> Result<Vec<u8>> {
    let app = u64::from(APP_FLASH_START)..u64::from(APP_FLASH_START) + u64::from(APP_FLASH_SIZE);
    let mut loaded: Vec<(u64, &[u8])> = segments
        .iter()
        .filter(|s| !s.data.is_empty())
        .map(|s| (u64::from(s.paddr), s.data))
        .collect();
    ensure!(!loaded.is_empty(), "the ELF has no loadable bytes");
    loaded.sort_by_key(|&(start, _)| start);

    let mut end_of_previous = app.start;
    for &(start, data) in &loaded {
        let end = start + data.len() as u64;
        ensure!(
            start >= app.start,
            "a LOAD segment starts at 0x{start:08x}, below the application start 0x{:08x} (the bootloader's flash)",
            app.start
        );
        ensure!(
            end <= app.end,
            "a LOAD segment ends at 0x{end:08x}, beyond the {} KiB application flash (0x{:08x}..0x{:08x})",
            APP_FLASH_SIZE / 1024,
            app.start,
            app.end
        );
        ensure!(start >= end_of_previous, "LOAD segments overlap at 0x{start:08x}");
        end_of_previous = end;
    }

    let mut image = vec![GAP_FILL; (end_of_previous - app.start) as usize];
    for (start, data) in loaded {
        let offset = (start - app.start) as usize;
        image[offset..offset + data.len()].copy_from_slice(data);
    }
    Ok(image)
}

/// Checks the Cortex-M vector table at the image's start: word 0, the initial stack pointer, lies in SRAM
/// (0x2000_0000..=0x2002_0000, the top being the usual value), and word 1, the reset handler, is a Thumb address
/// (odd) inside the image.
pub fn check_vector_table(image: &[u8]) -> Result<()> {
    let word = |i: usize| {
        image
            .get(4 * i..4 * i + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (Some(sp), Some(reset)) = (word(0), word(1)) else {
        bail!("the image ({} bytes) is too short to hold a vector table", image.len());
    };
    ensure!(
        (SRAM.start..=SRAM.end).contains(&sp),
        "vector table word 0 (initial stack pointer) is 0x{sp:08x}, not an SRAM address 0x{:08x}..=0x{:08x}",
        SRAM.start,
        SRAM.end
    );
    ensure!(
        reset & 1 == 1,
        "vector table word 1 (reset handler) 0x{reset:08x} lacks the Thumb bit"
    );
    let image_end = u64::from(APP_FLASH_START) + image.len() as u64;
    let handler = u64::from(reset & !1);
    ensure!(
        handler >= u64::from(APP_FLASH_START) && handler < image_end,
        "vector table word 1 (reset handler) 0x{reset:08x} lies outside the image 0x{APP_FLASH_START:08x}..0x{image_end:08x}"
    );
    Ok(())
}

/// The static memory the firmware uses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryUse {
    /// Image size: the flash the firmware occupies from [`APP_FLASH_START`].
    pub flash: u64,
    /// Allocated sections in SRAM (`.data`, `.bss`, `.uninit`, …), name and size.
    pub sram: Vec<(String, u64)>,
    /// Allocated sections in CCM.
    pub ccm: Vec<(String, u64)>,
}

impl MemoryUse {
    /// Accounts an image of `image_len` bytes and the allocated sections, by where they live at run time.
    pub fn of(image_len: usize, sections: &[AllocSection]) -> Self {
        let within = |range: &Range<u32>| -> Vec<(String, u64)> {
            sections
                .iter()
                .filter(|s| s.size > 0 && range.contains(&s.addr))
                .map(|s| (s.name.clone(), u64::from(s.size)))
                .collect()
        };
        Self {
            flash: image_len as u64,
            sram: within(&SRAM),
            ccm: within(&CCM),
        }
    }

    /// Bytes of static SRAM.
    pub fn sram_bytes(&self) -> u64 {
        self.sram.iter().map(|(_, size)| size).sum()
    }

    /// Bytes of CCM.
    pub fn ccm_bytes(&self) -> u64 {
        self.ccm.iter().map(|(_, size)| size).sum()
    }

    /// Three lines: flash, SRAM and CCM use.
    pub fn report(&self) -> String {
        let parts = |sections: &[(String, u64)]| {
            if sections.is_empty() {
                "none".to_string()
            } else {
                sections
                    .iter()
                    .map(|(name, size)| format!("{name} {size}"))
                    .collect::<Vec<_>>()
                    .join(" + ")
            }
        };
        let flash_kib = u64::from(APP_FLASH_SIZE / 1024);
        let sram_kib = u64::from((SRAM.end - SRAM.start) / 1024);
        let ccm_kib = u64::from((CCM.end - CCM.start) / 1024);
        format!(
            "flash: {} bytes ({}), {:.1} % of the {flash_kib} KiB application flash\n\
             SRAM:  {} bytes ({}) static ({}), {:.1} % of {sram_kib} KiB; the stack takes the rest\n\
             CCM:   {} bytes ({}) ({}), {:.1} % of {ccm_kib} KiB\n",
            self.flash,
            kib(self.flash),
            percent(self.flash, flash_kib * 1024),
            self.sram_bytes(),
            kib(self.sram_bytes()),
            parts(&self.sram),
            percent(self.sram_bytes(), sram_kib * 1024),
            self.ccm_bytes(),
            kib(self.ccm_bytes()),
            parts(&self.ccm),
            percent(self.ccm_bytes(), ccm_kib * 1024),
        )
    }
}

fn kib(bytes: u64) -> String {
    format!("{:.1} KiB", bytes as f64 / 1024.0)
}

fn percent(part: u64, whole: u64) -> f64 {
    100.0 * part as f64 / whole as f64
}

/// Refuses an image over `max_flash_kib` KiB or static SRAM use over `max_ram_kib` KiB.
pub fn check_budgets(usage: &MemoryUse, max_flash_kib: u32, max_ram_kib: u32) -> Result<()> {
    ensure!(
        usage.flash <= u64::from(max_flash_kib) * 1024,
        "the image takes {} bytes ({}), over --max-flash-kib {max_flash_kib}",
        usage.flash,
        kib(usage.flash)
    );
    let sram = usage.sram_bytes();
    ensure!(
        sram <= u64::from(max_ram_kib) * 1024,
        "static SRAM use is {sram} bytes ({}), over --max-ram-kib {max_ram_kib}",
        kib(sram)
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const BASE: u32 = APP_FLASH_START;

    fn seg(paddr: u32, data: &[u8]) -> LoadSegment<'_> {
        LoadSegment { paddr, data }
    }

    fn sec(name: &str, addr: u32, size: u32) -> AllocSection {
        AllocSection {
            name: name.to_string(),
            addr,
            size,
        }
    }

    /// A vector table with the given stack pointer and reset vector, then `extra` bytes of 0xAB.
    fn vectors(sp: u32, reset: u32, extra: usize) -> Vec<u8> {
        let mut v = Vec::new();
        v.extend_from_slice(&sp.to_le_bytes());
        v.extend_from_slice(&reset.to_le_bytes());
        v.resize(8 + extra, 0xAB);
        v
    }

    /// A fake sysroot under the system temp dir; `core` puts a `libcore-*.rlib` in the thumb target's lib.
    fn fake_sysroot(name: &str, core: Option<&str>) -> PathBuf {
        let root = env::temp_dir().join(format!("cfnav-sysroot-{}-{name}", std::process::id()));
        let _ = fs::remove_dir_all(&root);
        let host = root.join("lib/rustlib/x86_64-unknown-linux-gnu/lib");
        fs::create_dir_all(&host).unwrap();
        fs::write(host.join("libcore-0123.rlib"), b"").unwrap();
        if let Some(file) = core {
            let lib = root.join("lib/rustlib").join(TARGET_TRIPLE).join("lib");
            fs::create_dir_all(&lib).unwrap();
            fs::write(lib.join(file), b"").unwrap();
        }
        root
    }

    #[test]
    fn target_detection_needs_the_thumb_core_library() {
        let with = fake_sysroot("with", Some("libcore-9f2a.rlib"));
        let without = fake_sysroot("without", None);
        // The target folder alone (e.g. a half-removed install) is not enough.
        let empty = fake_sysroot("empty", Some("libcompiler_builtins-1.rlib"));
        assert!(target_installed(&with));
        assert!(!target_installed(&without));
        assert!(!target_installed(&empty));
        assert!(!target_installed(Path::new("/nonexistent/sysroot")));
        assert_eq!(target_plan(Some(&with), false), TargetPlan::Build);
        assert_eq!(target_plan(Some(&with), true), TargetPlan::Build);
        assert_eq!(target_plan(Some(&without), true), TargetPlan::AddWithRustup);
        assert_eq!(target_plan(Some(&without), false), TargetPlan::Stop);
        assert_eq!(target_plan(None, false), TargetPlan::Stop);
        assert_eq!(target_plan(None, true), TargetPlan::AddWithRustup);
        for root in [with, without, empty] {
            let _ = fs::remove_dir_all(root);
        }
    }

    #[test]
    fn missing_target_message_names_the_exact_command() {
        let m = missing_target_message("x");
        assert!(m.ends_with("\n    rustup target add thumbv7em-none-eabihf"), "{m}");
        assert_eq!(ADD_TARGET_COMMAND, format!("rustup target add {TARGET_TRIPLE}"));
    }

    #[test]
    fn this_toolchain_has_the_target_the_ci_needs() {
        // rust-toolchain.toml lists the target, so the sysroot that builds these tests has it.
        let sysroot = sysroot(&workspace_root()).expect("rustc --print sysroot");
        assert!(target_installed(&sysroot), "{}", sysroot.display());
    }

    #[test]
    fn image_places_segments_at_their_load_addresses_and_fills_gaps_with_ff() {
        let a = [1u8, 2, 3, 4];
        let b = [5u8, 6];
        let data = [7u8, 8, 9];
        // Out of order, with an empty (.bss-like) segment in RAM and a .data segment whose LMA is in flash.
        let segments = [
            seg(BASE + 10, &b),
            seg(0x2000_0100, &[]),
            seg(BASE, &a),
            seg(BASE + 12, &data),
        ];
        let image = build_image(&segments).unwrap();
        assert_eq!(image, [1, 2, 3, 4, 0, 0, 0, 0, 0, 0, 5, 6, 7, 8, 9]);
    }

    #[test]
    fn image_starts_at_the_application_start_even_if_the_first_segment_does_not() {
        let image = build_image(&[seg(BASE + 3, &[0x11])]).unwrap();
        assert_eq!(image, [0, 0, 0, 0x11]);
    }

    #[test]
    fn image_refuses_bytes_in_the_bootloader_sector() {
        let err = build_image(&[seg(0x0800_0000, &[0; 4]), seg(BASE, &[0; 4])])
            .unwrap_err()
            .to_string();
        assert!(err.contains("0x08000000") && err.contains("below"), "{err}");
        // One byte below the start is enough.
        assert!(build_image(&[seg(BASE - 1, &[0; 4])]).is_err());
    }

    #[test]
    fn image_may_fill_the_application_flash_but_not_overflow_it() {
        let full = vec![0u8; APP_FLASH_SIZE as usize];
        assert_eq!(build_image(&[seg(BASE, &full)]).unwrap().len(), full.len());
        let err = build_image(&[seg(BASE + 8, &full)]).unwrap_err().to_string();
        assert!(err.contains("beyond the 1008 KiB"), "{err}");
        // A RAM address with file contents (a section without a flash LMA) is refused too.
        assert!(build_image(&[seg(BASE, &[0; 8]), seg(0x2000_0000, &[1])]).is_err());
    }

    #[test]
    fn image_refuses_overlaps_and_emptiness() {
        assert!(
            build_image(&[seg(BASE, &[0; 8]), seg(BASE + 4, &[0; 8])])
                .unwrap_err()
                .to_string()
                .contains("overlap")
        );
        assert!(build_image(&[]).is_err());
        assert!(build_image(&[seg(0x2000_0000, &[])]).is_err());
    }

    #[test]
    fn vector_table_checks() {
        assert!(check_vector_table(&vectors(0x2002_0000, BASE + 0x189, 0x200)).is_ok());
        assert!(check_vector_table(&vectors(0x2000_0400, BASE + 9, 4)).is_ok());
        // Stack pointer outside SRAM: erased flash, CCM, one past the top.
        for sp in [0xFFFF_FFFF, 0x1001_0000, 0x2002_0004, 0x1FFF_FFFC] {
            let err = check_vector_table(&vectors(sp, BASE + 9, 0x10))
                .unwrap_err()
                .to_string();
            assert!(err.contains("word 0"), "{err}");
        }
        // Reset handler without the Thumb bit, outside the image, or below it.
        assert!(check_vector_table(&vectors(0x2002_0000, BASE + 8, 0x10)).is_err());
        assert!(check_vector_table(&vectors(0x2002_0000, BASE + 0x19, 0x10)).is_err());
        assert!(check_vector_table(&vectors(0x2002_0000, 0x0800_0101, 0x10)).is_err());
        // Too short.
        assert!(check_vector_table(&[0, 0, 2, 0x20]).is_err());
    }

    #[test]
    fn memory_use_sorts_sections_by_region() {
        let sections = [
            sec(".vector_table", BASE, 0x188),
            sec(".text", BASE + 0x188, 0x3000),
            sec(".data", 0x2000_0000, 80),
            sec(".bss", 0x2000_0050, 324),
            sec(".uninit", 0x2000_0194, 1024),
            sec(".ccmram", 0x1000_0000, 37012),
            sec(".empty", 0x2000_0600, 0),
        ];
        let usage = MemoryUse::of(19_744, &sections);
        assert_eq!(usage.flash, 19_744);
        assert_eq!(usage.sram_bytes(), 80 + 324 + 1024);
        assert_eq!(
            usage.sram.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>(),
            [".data", ".bss", ".uninit"]
        );
        assert_eq!(usage.ccm, [(".ccmram".to_string(), 37012)]);
        let report = usage.report();
        assert!(
            report.contains("flash: 19744 bytes (19.3 KiB), 1.9 % of the 1008 KiB"),
            "{report}"
        );
        assert!(
            report.contains("SRAM:  1428 bytes (1.4 KiB) static (.data 80 + .bss 324 + .uninit 1024)"),
            "{report}"
        );
        assert!(
            report.contains("CCM:   37012 bytes (36.1 KiB) (.ccmram 37012), 56.5 % of 64 KiB"),
            "{report}"
        );
        assert_eq!(report.lines().count(), 3);
    }

    /// The budgets a user gets without flags are the chip's: 1008 KiB of application flash (memory.x's
    /// FLASH region) and 128 KiB of SRAM. A tighter regression budget is CI's to ask for.
    #[test]
    fn default_budgets_are_the_chips_limits() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            firmware: FirmwareArgs,
        }
        let args = Cli::try_parse_from(["firmware"]).unwrap().firmware;
        assert_eq!((args.max_flash_kib, args.max_ram_kib), (1008, 128));
        let memory_x = include_str!("../../memory.x");
        assert!(
            memory_x.contains("FLASH  : ORIGIN = 0x08004000, LENGTH = 1024K - 16K"),
            "{memory_x}"
        );
        assert!(
            memory_x.contains("RAM    : ORIGIN = 0x20000000, LENGTH = 128K"),
            "{memory_x}"
        );
    }

    #[test]
    fn budgets_are_inclusive_limits() {
        let usage = MemoryUse {
            flash: 256 * 1024,
            sram: vec![(".bss".into(), 100 * 1024)],
            ccm: vec![],
        };
        assert!(check_budgets(&usage, 256, 100).is_ok());
        let err = check_budgets(&usage, 255, 100).unwrap_err().to_string();
        assert!(err.contains("--max-flash-kib 255"), "{err}");
        let err = check_budgets(&usage, 256, 99).unwrap_err().to_string();
        assert!(err.contains("--max-ram-kib 99"), "{err}");
    }

    #[test]
    fn finds_the_firmware_artifact_in_cargo_json() {
        let line = r#"{"reason":"compiler-artifact","package_id":"path+file:///w#cfnav@0.1.0","target":{"kind":["bin"],"crate_types":["bin"],"name":"firmware","src_path":"/w/src/main.rs"},"executable":"/t/thumbv7em-none-eabihf/release/firmware","fresh":true}"#;
        assert_eq!(
            firmware_artifact(line),
            Some(PathBuf::from("/t/thumbv7em-none-eabihf/release/firmware"))
        );
        let lib = r#"{"reason":"compiler-artifact","target":{"kind":["lib"],"name":"cfnav"},"executable":null}"#;
        let build_script = r#"{"reason":"compiler-artifact","target":{"kind":["custom-build"],"name":"build-script-build"},"executable":null}"#;
        let finished = r#"{"reason":"build-finished","success":true}"#;
        for other in [lib, build_script, finished, "", "Compiling cfnav", "{"] {
            assert_eq!(firmware_artifact(other), None, "{other}");
        }
    }

    #[test]
    fn target_dir_is_derived_from_the_artifact_path() {
        let elf = Path::new("/tmp/t/thumbv7em-none-eabihf/release/firmware");
        assert_eq!(target_dir_from_artifact(elf), Some(PathBuf::from("/tmp/t")));
        assert_eq!(target_dir_from_artifact(Path::new("/tmp/t/debug/firmware")), None);
    }

    // --- a tiny ELF writer, to test `read_elf` on real bytes ----------------------------------------------------

    struct TestSegment {
        vaddr: u32,
        paddr: u32,
        data: Vec<u8>,
        memsz: u32,
    }

    struct TestSection {
        name: &'static str,
        addr: u32,
        size: u32,
        alloc: bool,
    }

    fn push16(v: &mut Vec<u8>, x: u16) {
        v.extend_from_slice(&x.to_le_bytes());
    }

    fn push32(v: &mut Vec<u8>, x: u32) {
        v.extend_from_slice(&x.to_le_bytes());
    }

    /// ELF32 little-endian: header, program headers, segment contents, .shstrtab, section headers.
    fn make_elf(machine: u16, segments: &[TestSegment], sections: &[TestSection]) -> Vec<u8> {
        const EHSIZE: u32 = 52;
        const PHSIZE: u32 = 32;
        const SHSIZE: u32 = 40;
        let phoff = EHSIZE;
        let mut offset = phoff + PHSIZE * segments.len() as u32;
        let mut seg_offsets = Vec::new();
        for s in segments {
            seg_offsets.push(offset);
            offset += s.data.len() as u32;
        }
        let mut shstrtab = vec![0u8];
        let mut name_offsets = Vec::new();
        for name in sections.iter().map(|s| s.name).chain([".shstrtab"]) {
            name_offsets.push(shstrtab.len() as u32);
            shstrtab.extend_from_slice(name.as_bytes());
            shstrtab.push(0);
        }
        let shstrtab_offset = offset;
        let shoff = (shstrtab_offset + shstrtab.len() as u32).next_multiple_of(4);
        let shnum = sections.len() as u16 + 2;

        let mut v = Vec::new();
        v.extend_from_slice(&[0x7f, b'E', b'L', b'F', 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
        push16(&mut v, 2); // ET_EXEC
        push16(&mut v, machine);
        push32(&mut v, 1);
        push32(&mut v, BASE + 0x189); // entry
        push32(&mut v, phoff);
        push32(&mut v, shoff);
        push32(&mut v, 0x0500_0400); // EABI5, hard float
        push16(&mut v, EHSIZE as u16);
        push16(&mut v, PHSIZE as u16);
        push16(&mut v, segments.len() as u16);
        push16(&mut v, SHSIZE as u16);
        push16(&mut v, shnum);
        push16(&mut v, shnum - 1); // .shstrtab is last
        for (s, &off) in segments.iter().zip(&seg_offsets) {
            for word in [1, off, s.vaddr, s.paddr, s.data.len() as u32, s.memsz, 4, 4] {
                push32(&mut v, word);
            }
        }
        for s in segments {
            v.extend_from_slice(&s.data);
        }
        v.extend_from_slice(&shstrtab);
        v.resize(shoff as usize, 0);
        v.extend_from_slice(&[0; SHSIZE as usize]); // the null section
        for (s, &name) in sections.iter().zip(&name_offsets) {
            let flags = if s.alloc { elf::SHF_ALLOC | elf::SHF_WRITE } else { 0 };
            let kind = if s.alloc && s.addr >= SRAM.start {
                elf::SHT_NOBITS
            } else {
                elf::SHT_PROGBITS
            };
            for word in [name, kind, flags, s.addr, 0, s.size, 0, 0, 4, 0] {
                push32(&mut v, word);
            }
        }
        let strtab_name = *name_offsets.last().unwrap();
        for word in [
            strtab_name,
            elf::SHT_STRTAB,
            0,
            0,
            shstrtab_offset,
            shstrtab.len() as u32,
            0,
            0,
            1,
            0,
        ] {
            push32(&mut v, word);
        }
        v
    }

    fn firmware_like_elf(sp: u32) -> Vec<u8> {
        let mut text = vectors(sp, BASE + 0x9, 0x20);
        text.truncate(0x28);
        let rodata = b"cfnav\0\0\0".to_vec();
        let data = vec![0x5A; 8];
        make_elf(
            elf::EM_ARM,
            &[
                TestSegment {
                    vaddr: BASE,
                    paddr: BASE,
                    data: text,
                    memsz: 0x28,
                },
                TestSegment {
                    vaddr: BASE + 0x30,
                    paddr: BASE + 0x30,
                    data: rodata,
                    memsz: 8,
                },
                TestSegment {
                    vaddr: 0x2000_0000,
                    paddr: BASE + 0x38,
                    data,
                    memsz: 8,
                },
                TestSegment {
                    vaddr: 0x2000_0008,
                    paddr: 0x2000_0008,
                    data: vec![],
                    memsz: 0x100,
                },
                TestSegment {
                    vaddr: 0x1000_0000,
                    paddr: 0x1000_0000,
                    data: vec![],
                    memsz: 0x9000,
                },
            ],
            &[
                TestSection {
                    name: ".text",
                    addr: BASE,
                    size: 0x28,
                    alloc: true,
                },
                TestSection {
                    name: ".rodata",
                    addr: BASE + 0x30,
                    size: 8,
                    alloc: true,
                },
                TestSection {
                    name: ".data",
                    addr: 0x2000_0000,
                    size: 8,
                    alloc: true,
                },
                TestSection {
                    name: ".bss",
                    addr: 0x2000_0008,
                    size: 0x100,
                    alloc: true,
                },
                TestSection {
                    name: ".ccmram",
                    addr: 0x1000_0000,
                    size: 0x9000,
                    alloc: true,
                },
                TestSection {
                    name: ".defmt",
                    addr: 0,
                    size: 0x2d,
                    alloc: false,
                },
            ],
        )
    }

    #[test]
    fn converts_a_firmware_like_elf() {
        let bytes = firmware_like_elf(0x2002_0000);
        let layout = read_elf(&bytes).unwrap();
        assert_eq!(layout.segments.len(), 5);
        let image = build_image(&layout.segments).unwrap();
        assert_eq!(image.len(), 0x40);
        assert_eq!(&image[..8], &vectors(0x2002_0000, BASE + 9, 0)[..]);
        assert_eq!(&image[0x28..0x30], &[GAP_FILL; 8]); // gap between .text and .rodata
        assert_eq!(&image[0x30..0x38], b"cfnav\0\0\0");
        assert_eq!(&image[0x38..0x40], &[0x5A; 8]); // .data's initial values at its load address
        check_vector_table(&image).unwrap();

        let usage = MemoryUse::of(image.len(), &layout.sections);
        assert_eq!(usage.sram, [(".data".to_string(), 8), (".bss".to_string(), 0x100)]);
        assert_eq!(usage.ccm_bytes(), 0x9000);
        assert!(layout.sections.iter().all(|s| s.name != ".defmt"));
    }

    #[test]
    fn a_bad_vector_table_in_the_elf_is_refused() {
        let bytes = firmware_like_elf(0x1001_0000);
        let image = build_image(&read_elf(&bytes).unwrap().segments).unwrap();
        assert!(check_vector_table(&image).is_err());
    }

    #[test]
    fn read_elf_refuses_non_arm_and_garbage() {
        let x86 = make_elf(elf::EM_386, &[], &[]);
        assert!(read_elf(&x86).unwrap_err().to_string().contains("not ARM"));
        assert!(read_elf(b"definitely not an ELF file, but long enough to hold a header....").is_err());
        assert!(read_elf(&[]).is_err());
        // A segment pointing past the end of the file.
        let mut bytes = firmware_like_elf(0x2002_0000);
        let p_offset = 52 + 4;
        bytes[p_offset..p_offset + 4].copy_from_slice(&0x00FF_0000u32.to_le_bytes());
        assert!(read_elf(&bytes).unwrap_err().to_string().contains("outside the file"));
    }
}
