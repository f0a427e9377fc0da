//! Expected figures: `ci/expected/NAME.txt`, one `key value` line per figure (`#` lines are comments), that a
//! CI step compares its run against and `cargo xtask bless STEP` rewrites from a run.
//!
//! Each figure has its own rule ([`Rule`]): exact, or within a relative tolerance of the expected value. A
//! figure the file lacks, or a file key the run did not produce, fails the comparison, so a renamed figure
//! cannot pass silently.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// How a figure is compared with its expected value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rule {
    /// The same text (integers, and floats in Rust's shortest round-trip form).
    Exact,
    /// A number within this fraction of the expected one (0.02 = ±2 %).
    Within(f64),
}

/// One figure of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    pub key: String,
    pub value: String,
    pub rule: Rule,
}

impl Figure {
    pub fn exact(key: &str, value: impl std::fmt::Display) -> Self {
        Self {
            key: key.into(),
            value: value.to_string(),
            rule: Rule::Exact,
        }
    }
    pub fn within(key: &str, value: impl std::fmt::Display, fraction: f64) -> Self {
        Self {
            key: key.into(),
            value: value.to_string(),
            rule: Rule::Within(fraction),
        }
    }
}

/// Reads `key value` lines (the value is the rest of the line, trimmed).
pub fn parse(text: &str) -> Result<BTreeMap<String, String>, String> {
    let mut out = BTreeMap::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (key, value) = line
            .split_once(char::is_whitespace)
            .ok_or_else(|| format!("line {}: `{line}` is not `key value`", i + 1))?;
        if out.insert(key.to_string(), value.trim().to_string()).is_some() {
            return Err(format!("line {}: `{key}` given twice", i + 1));
        }
    }
    Ok(out)
}

/// The file's text for `figures`, with `header` as its comment lines.
pub fn render(header: &str, figures: &[Figure]) -> String {
    let mut out = String::new();
    for line in header.lines() {
        let _ = writeln!(out, "# {line}");
    }
    for f in figures {
        let _ = writeln!(out, "{} {}", f.key, f.value);
    }
    out
}

/// Compares a run's `figures` with the expected `text`: every difference, one line each (empty: all match).
pub fn compare(text: &str, figures: &[Figure]) -> Result<Vec<String>, String> {
    let expected = parse(text)?;
    let mut problems = Vec::new();
    for f in figures {
        let Some(want) = expected.get(&f.key) else {
            problems.push(format!("{}: {} (not in the expected file)", f.key, f.value));
            continue;
        };
        match f.rule {
            Rule::Exact if *want == f.value => {}
            Rule::Exact => problems.push(format!("{}: {} (expected {want} exactly)", f.key, f.value)),
            Rule::Within(fraction) => {
                let (Ok(got), Ok(w)) = (f.value.parse::<f64>(), want.parse::<f64>()) else {
                    problems.push(format!("{}: {} vs expected {want}: not numbers", f.key, f.value));
                    continue;
                };
                if (got - w).abs() > fraction * w.abs() {
                    problems.push(format!(
                        "{}: {} (expected {want} within ±{:.0} %, off by {:+.2} %)",
                        f.key,
                        f.value,
                        fraction * 100.0,
                        100.0 * (got - w) / w
                    ));
                }
            }
        }
    }
    for key in expected.keys() {
        if !figures.iter().any(|f| &f.key == key) {
            problems.push(format!("{key}: in the expected file, not produced by the run"));
        }
    }
    Ok(problems)
}

/// Compares `figures` with `path` (or, with `bless`, writes them there). `Err` lists every difference and
/// the command that accepts the new figures.
pub fn check_or_bless(path: &Path, header: &str, figures: &[Figure], bless: bool, step: &str) -> Result<(), String> {
    if bless {
        std::fs::write(path, render(header, figures)).map_err(|e| format!("{}: {e}", path.display()))?;
        println!("blessed {} ({} figures)", path.display(), figures.len());
        return Ok(());
    }
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: {e} (write it with `cargo xtask bless {step}`)", path.display()))?;
    let problems = compare(&text, figures)?;
    if problems.is_empty() {
        println!("{}: {} figures as expected", path.display(), figures.len());
        Ok(())
    } else {
        Err(format!(
            "{} differs from this run:\n  {}\n(if the change is intended: `cargo xtask bless {step}` and commit the file)",
            path.display(),
            problems.join("\n  ")
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rendered_file_compares_equal_to_its_figures() {
        let figures = [Figure::exact("runs", 200), Figure::within("flash_bytes", 265_256, 0.02)];
        let text = render("a header\nsecond line", &figures);
        assert!(text.starts_with("# a header\n# second line\n"));
        assert_eq!(compare(&text, &figures).unwrap(), Vec::<String>::new());
    }

    #[test]
    fn exact_figures_differ_on_any_change() {
        let text = "median 0.0252\n";
        assert!(compare(text, &[Figure::exact("median", 0.0252)]).unwrap().is_empty());
        let p = compare(text, &[Figure::exact("median", 0.02521)]).unwrap();
        assert_eq!(p.len(), 1, "{p:?}");
    }

    #[test]
    fn tolerances_are_relative_to_the_expected_value() {
        let text = "n 1000\n";
        assert!(compare(text, &[Figure::within("n", 1020, 0.02)]).unwrap().is_empty());
        assert!(compare(text, &[Figure::within("n", 980, 0.02)]).unwrap().is_empty());
        assert_eq!(compare(text, &[Figure::within("n", 1021, 0.02)]).unwrap().len(), 1);
        assert_eq!(compare(text, &[Figure::within("n", 979, 0.02)]).unwrap().len(), 1);
        assert_eq!(compare(text, &[Figure::within("n", "x", 0.02)]).unwrap().len(), 1);
    }

    #[test]
    fn missing_and_extra_keys_fail() {
        let text = "a 1\nb 2\n";
        let p = compare(text, &[Figure::exact("a", 1), Figure::exact("c", 3)]).unwrap();
        assert_eq!(p.len(), 2, "{p:?}");
        assert!(
            p.iter().any(|l| l.starts_with("c:")) && p.iter().any(|l| l.starts_with("b:")),
            "{p:?}"
        );
    }

    #[test]
    fn malformed_files_are_refused() {
        assert!(parse("just-a-key\n").is_err());
        assert!(parse("a 1\na 2\n").is_err());
        assert_eq!(parse("# c\n\n a  1 2 \n").unwrap()["a"], "1 2");
    }
}
