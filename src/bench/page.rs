//! A dated results page (`lancer bench … --report FILE.md`): the machine, the adapter and
//! driver, lancer's version and commit, the date (UTC), the command, the tables as printed
//! and the charts, drawn next to the page and linked relatively. Written atomically.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use crate::error::Result;

use super::markdown::page_body;
use super::BenchReport;

/// The machine a bench ran on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Machine {
    /// The CPU model (/proc/cpuinfo's "model name"), or "unknown CPU".
    pub cpu: String,
    /// Logical cores the process may use.
    pub cores: usize,
    /// Operating system and architecture, e.g. "linux x86_64".
    pub os: String,
    /// The load averages over 1, 5 and 15 minutes (/proc/loadavg), where known.
    pub load: Option<String>,
}

impl Machine {
    /// This machine, now.
    pub fn here() -> Machine {
        let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let cpu = (cpuinfo.lines())
            .find_map(|l| {
                let (key, value) = l.split_once(':')?;
                (key.trim() == "model name").then(|| value.trim().to_string())
            })
            .unwrap_or_else(|| "unknown CPU".into());
        let load = std::fs::read_to_string("/proc/loadavg").ok().map(|l| {
            let fields: Vec<&str> = l.split_whitespace().take(3).collect();
            fields.join(" ")
        });
        Machine {
            cpu,
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            os: format!("{} {}", std::env::consts::OS, std::env::consts::ARCH),
            load,
        }
    }
}

/// lancer's version and the commit of the source tree it was built from: `git rev-parse
/// --short HEAD` in that tree when it is still there and is a git checkout (with a note when
/// tracked files have uncommitted changes), else "commit unknown".
pub fn version() -> String {
    let version = env!("CARGO_PKG_VERSION");
    match commit() {
        Some(c) => format!("{version}, commit {c}"),
        None => format!("{version}, commit unknown"),
    }
}

fn commit() -> Option<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let git = |args: &[&str]| {
        let out = std::process::Command::new("git")
            .arg("-C")
            .arg(dir)
            .args(args)
            .stderr(std::process::Stdio::null())
            .output()
            .ok()?;
        out.status
            .success()
            .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
    };
    // The tree must be lancer's own checkout, not a folder inside some other repository.
    let top = git(&["rev-parse", "--show-toplevel"])?;
    if std::fs::canonicalize(&top).ok()? != std::fs::canonicalize(dir).ok()? {
        return None;
    }
    let hash = git(&["rev-parse", "--short", "HEAD"])?;
    let dirty =
        git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
    Some(match dirty {
        true => format!("{hash} (tracked files had uncommitted changes)"),
        false => hash,
    })
}

/// Year, month and day of a day counted from 1970-01-01 (the proleptic Gregorian calendar).
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + (month <= 2) as i64;
    (year, month, day)
}

/// A time as "YYYY-MM-DD HH:MM UTC".
pub fn utc(time: SystemTime) -> String {
    let secs = match time.duration_since(UNIX_EPOCH) {
        Ok(d) => d.as_secs() as i64,
        Err(e) => -(e.duration().as_secs() as i64),
    };
    let (y, m, d) = civil_from_days(secs.div_euclid(86_400));
    let s = secs.rem_euclid(86_400);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02} UTC",
        s / 3600,
        s / 60 % 60
    )
}

/// A chart's path beside a page: `NAME.png` for suffix "", `NAME-SUFFIX.png` otherwise.
pub fn beside(page: &Path, suffix: &str) -> PathBuf {
    let stem = page
        .file_stem()
        .map_or("report".into(), |s| s.to_string_lossy().into_owned());
    match suffix {
        "" => page.with_file_name(format!("{stem}.png")),
        s => page.with_file_name(format!("{stem}-{s}.png")),
    }
}

/// Every file a page at `page` writes (the page and its charts), to check before work.
pub fn outputs<R: BenchReport>(page: &Path) -> Vec<PathBuf> {
    let mut out = vec![page.to_path_buf()];
    if cfg!(feature = "charts") {
        out.extend(R::CHARTS.iter().map(|s| beside(page, s)));
    }
    out
}

/// The page's markdown: `command` is the command line that ran the bench, `lancer` the
/// version that ran it ([`version`]), `charts` the chart files (linked by their names: they
/// lie beside the page).
pub fn markdown<R: BenchReport>(
    report: &R,
    command: &str,
    lancer: &str,
    time: SystemTime,
    charts: &[PathBuf],
) -> String {
    let machine = Machine::here();
    let date = utc(time);
    let day = date.split(' ').next().unwrap_or_default();
    let mut page = format!("# {}, {day}\n\n", report.title());
    page += &format!("- **date**: {date}\n");
    page += &format!(
        "- **machine**: {}, {} cores ({})\n",
        machine.cpu, machine.cores, machine.os
    );
    if let Some(load) = &machine.load {
        page += &format!("- **load average** (1, 5, 15 min, when written): {load}\n");
    }
    page += &format!("- **CPU threads**: {}\n", super::cpu_threads());
    page += &format!(
        "- **adapter and driver**: {}\n",
        report.adapter().unwrap_or_else(|| "none (CPU only)".into())
    );
    page += &format!("- **lancer**: {lancer}\n");
    page += &format!("- **command**:\n\n  ```sh\n  {command}\n  ```\n\n");
    page += "## Results\n\n";
    page += &page_body(&report.text());
    if !charts.is_empty() {
        page += if charts.len() == 1 {
            "\n## Chart\n"
        } else {
            "\n## Charts\n"
        };
        for c in charts {
            let name = c.file_name().unwrap_or_default().to_string_lossy();
            page += &format!("\n![{name}]({name})\n");
        }
    }
    page
}

/// A command line as a shell takes it: `lancer` and the arguments `args`, each quoted
/// where a shell would read it otherwise (the page's "command" line).
pub fn shell_command(args: impl IntoIterator<Item = String>) -> String {
    let quote = |a: String| {
        let plain = |c: char| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c);
        match !a.is_empty() && a.chars().all(plain) {
            true => a,
            false => format!("'{}'", a.replace('\'', r"'\''")),
        }
    };
    let args = args.into_iter().map(quote);
    std::iter::once("lancer".to_string())
        .chain(args)
        .collect::<Vec<_>>()
        .join(" ")
}

/// Writes the results page `path` (atomically, replacing it) and, with the `charts`
/// feature, its charts beside it ([`beside`]).
pub fn write<R: BenchReport>(path: &Path, report: &R, command: &str) -> Result<()> {
    // The tree's state before the page's own files are written over (they would count as
    // uncommitted changes).
    let lancer = version();
    #[cfg(feature = "charts")]
    let charts = report.draw_charts(&outputs::<R>(path)[1..])?;
    #[cfg(not(feature = "charts"))]
    let charts: Vec<PathBuf> = Vec::new();
    let text = markdown(report, command, &lancer, SystemTime::now(), &charts);
    crate::output::write_bytes(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn the_command_is_quoted_as_a_shell_reads_it() {
        let args = [
            "bench",
            "layouts",
            "my scene.obj",
            "--report",
            "it's.md",
            "",
        ];
        assert_eq!(
            shell_command(args.map(String::from)),
            r"lancer bench layouts 'my scene.obj' --report 'it'\''s.md' ''"
        );
    }

    #[test]
    fn dates_are_utc_days() {
        let at = |s: u64| utc(UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), "1970-01-01 00:00 UTC");
        assert_eq!(at(951_782_400), "2000-02-29 00:00 UTC");
        assert_eq!(at(1_796_172_420), "2026-12-02 00:47 UTC");
    }

    #[test]
    fn charts_lie_beside_the_page() {
        let p = Path::new("docs/src/results/run.md");
        assert_eq!(beside(p, ""), Path::new("docs/src/results/run.png"));
        assert_eq!(beside(p, "cpu"), Path::new("docs/src/results/run-cpu.png"));
    }
}
