//! Report files: checked before the work (never over an input, never two outputs in one
//! file), staged and renamed together after it succeeds; stdout that fails is an error,
//! a closed pipe quiet.

use crate::Error;
use crate::app::Report;
use crate::data::Staged;
use std::path::{Path, PathBuf};

/// Checks before any work that the output given by the flag `flag` (its long name, e.g.
/// `output`) can be written: not one of the `inputs`, in an existing directory. "-"
/// (stdout) always can.
///
/// # Errors
/// [`Error::InvalidOption`] (option `flag`) naming the path when it is an input or its
/// folder is missing.
pub fn check_as(flag: &str, path: &Path, inputs: &[PathBuf]) -> crate::Result<()> {
    if path.as_os_str() == "-" {
        return Ok(());
    }
    if let Some(input) = inputs.iter().find(|i| same_file(path, i)) {
        return Err(Error::InvalidOption {
            option: flag.into(),
            reason: format!("{} is an input of this command: refusing to overwrite it", input.display()),
        });
    }
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(Error::InvalidOption {
            option: flag.into(),
            reason: format!("folder {} of {} does not exist", dir.display(), path.display()),
        });
    }
    Ok(())
}

/// Checks before any work that every output `(flag, path)` given can be written
/// ([`check_as`]: not an input, in an existing folder) and that no two outputs are one file
/// (the second would replace the first). `inputs`: every file the command reads (logs,
/// `--params`, `--config`).
///
/// # Errors
/// [`Error::InvalidOption`] naming the flag and the path.
pub fn check_all(outputs: &[(&str, Option<&Path>)], inputs: &[PathBuf]) -> crate::Result<()> {
    let given: Vec<(&str, &Path)> =
        outputs.iter().filter_map(|(f, p)| p.filter(|p| p.as_os_str() != "-").map(|p| (*f, p))).collect();
    for (i, (flag, path)) in given.iter().enumerate() {
        check_as(flag, path, inputs)?;
        if let Some((other, _)) = given[..i].iter().find(|(_, q)| same_file(q, path)) {
            return Err(Error::InvalidOption {
                option: (*flag).into(),
                reason: format!(
                    "{} is also the output of {other}: give each output its own file",
                    path.display()
                ),
            });
        }
    }
    Ok(())
}

/// Whether two paths name one file (by their canonical forms when they exist).
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// Stages `text` for `path` ("-" = stdout, written at once): a temporary file beside it,
/// renamed over it when the command commits all its outputs together, so that a reader or
/// a concurrent run never sees a partial file and a failure leaves every old file intact.
///
/// # Errors
/// [`Error::Write`] with the path when the temporary file cannot be written.
pub fn write(staged: &mut Staged, path: &Path, text: &str) -> crate::Result<()> {
    if path.as_os_str() == "-" {
        return stdout(&format!("{text}\n"));
    }
    staged.write(path, |f| {
        f.write_all(text.as_bytes())?;
        f.write_all(b"\n")
    })
}

/// Writes `text` to stdout and flushes it. A reader that went away (`| head`: a broken
/// pipe) is no error and stops the output quietly; any other failure (a full disk behind
/// `> file`, `/dev/full`) is.
///
/// # Errors
/// [`Error::Write`] (path `stdout`) with the cause.
pub fn stdout(text: &str) -> crate::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.map_err(|source| Error::Write { path: "stdout".into(), source }),
    }
}

/// The report flags of the fitting subcommands (`fluxmap`, `saturation`, `standstill`,
/// `mechanics`).
#[derive(clap::Args, Debug)]
pub struct ReportArgs {
    /// Write the fit as JSON ("-" for stdout).
    #[arg(long, value_name = "PATH.json")]
    pub json: Option<PathBuf>,
    /// Print nothing on stdout but the JSON (if it goes there).
    #[arg(long, short)]
    pub quiet: bool,
}

impl ReportArgs {
    /// Checks that the JSON output overwrites none of the `inputs`, then runs the fit
    /// (`report`, which checks the inputs themselves) and reports it ([`emit`]); whether the
    /// `what` is trusted.
    ///
    /// # Errors
    /// Those of [`check_all`], `report` and the output.
    pub fn run(
        &self,
        inputs: &[PathBuf],
        what: &str,
        report: impl FnOnce() -> crate::Result<Report>,
    ) -> crate::Result<bool> {
        check_all(&[("--json", self.json.as_deref())], inputs)?;
        emit(&report()?, self.json.as_deref(), self.quiet, what)
    }
}

/// Prints the text of `report` (unless `quiet` or the JSON goes to stdout), writes its JSON
/// to `json` (all or nothing), says on stderr why the `what` is not to be trusted; whether
/// it is.
///
/// # Errors
/// An output that cannot be written (nothing is written then).
pub fn emit(report: &Report, json: Option<&Path>, quiet: bool, what: &str) -> crate::Result<bool> {
    if !(quiet || json.is_some_and(|p| p.as_os_str() == "-")) {
        stdout(&report.text)?;
    }
    let mut staged = Staged::new();
    if let Some(path) = json {
        write(&mut staged, path, &report.json)?;
    }
    staged.commit()?;
    if !report.untrusted.is_empty() {
        eprintln!("warning: the {what} is not to be trusted ({}); exit code 3", report.untrusted.join(", "));
    }
    Ok(report.trusted())
}
