//! The files a command will write, checked before any work starts: a render that runs for
//! a minute must not then fail on a misspelt `--png` directory, and two outputs must not
//! be one file (`--vcd x.gtkw` would have its GTKWave save file written over it).

use std::fs::OpenOptions;
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};

/// The output files of one command, each with the option that names it.
#[derive(Default)]
pub struct Outputs {
    files: Vec<(String, PathBuf)>,
}

impl Outputs {
    /// Checks that `path` (given by `what`, e.g. `--png`) can be written and is not
    /// another output of the command.
    pub fn add(&mut self, what: &str, path: &Path) -> Result<()> {
        let shown = path.display();
        if let Some((other, _)) = self.files.iter().find(|(_, p)| same_file(p, path)) {
            bail!("{what} `{shown}` is also {other}: give each output its own file");
        }
        if path.as_os_str().is_empty() {
            bail!("{what}: the file name is empty");
        }
        if path.is_dir() {
            bail!("{what} `{shown}` is a directory");
        }
        let parent = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        if !parent.is_dir() {
            bail!(
                "{what} `{shown}`: there is no directory `{}`",
                parent.display()
            );
        }
        // Opening for writing (without truncating) is the only sure test of permissions; a
        // file this probe creates is removed again, so a failed run leaves nothing behind.
        let existed = path.exists();
        if let Err(e) = OpenOptions::new().append(true).create(true).open(path) {
            bail!("{what} `{shown}`: cannot write: {e}");
        }
        if !existed {
            let _ = std::fs::remove_file(path);
        }
        self.files.push((what.to_string(), path.to_path_buf()));
        Ok(())
    }

    /// [`Outputs::add`] for an optional output.
    pub fn add_opt(&mut self, what: &str, path: Option<&PathBuf>) -> Result<()> {
        match path {
            Some(p) => self.add(what, p),
            None => Ok(()),
        }
    }
}

/// Whether two paths name one regular file (the same text, or the same file once both
/// exist); devices such as `/dev/null` may take several outputs.
fn same_file(a: &Path, b: &Path) -> bool {
    if std::fs::metadata(a).is_ok_and(|m| !m.is_file()) {
        return false;
    }
    if a == b {
        return true;
    }
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => {
            // A file not yet written: compare its directory and name.
            let dir = |p: &Path| {
                p.parent()
                    .filter(|d| !d.as_os_str().is_empty())
                    .unwrap_or(Path::new("."))
                    .canonicalize()
                    .ok()
            };
            a.file_name() == b.file_name() && dir(a).is_some() && dir(a) == dir(b)
        }
    }
}
