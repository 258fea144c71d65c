//! The log paths of a fit: refused when given twice or when a word meant as a flag's
//! value landed among them; named by the shortest path suffix that tells them apart.

use crate::Error;
use std::path::{Component, Path, PathBuf};

/// Checks the log paths before anything is read.
///
/// # Errors
/// [`Error::InvalidOption`] (option `LOG`) naming the path
/// - when a path is not a file and reads as a number (`greybox fit --huber 2.0 log.csv`:
///   `--huber` takes its value only as `--huber=2.0`);
/// - when the same log is given twice, as typed or after resolving `.`, `..` and links
///   (fitting it twice would shrink the standard errors by √2).
pub fn check_paths(paths: &[PathBuf]) -> crate::Result<()> {
    let bad = |reason: String| Error::InvalidOption { option: "LOG".into(), reason };
    for p in paths {
        let s = p.to_string_lossy();
        if !p.exists() && s.parse::<f64>().is_ok() {
            return Err(bad(format!(
                "`{s}` is not a file but a number: a flag with an optional value takes it only after `=` \
                 (e.g. --huber={s}); a separate word is read as a log"
            )));
        }
    }
    let keys: Vec<PathBuf> = paths.iter().map(|p| p.canonicalize().unwrap_or_else(|_| p.clone())).collect();
    for (i, k) in keys.iter().enumerate() {
        if let Some(j) = keys[..i].iter().position(|x| x == k) {
            let same = if paths[i] == paths[j] {
                "given twice".to_string()
            } else {
                format!("is the same file as {}", paths[j].display())
            };
            return Err(bad(format!(
                "{} {same}: a log fitted twice counts its samples twice and shrinks the standard errors by √2",
                paths[i].display()
            )));
        }
    }
    Ok(())
}

/// Names of the logs for the report's per-log rows: each log's `stem` (the experiment name
/// the reader gave it) when the stems differ, else the shortest suffix of its resolved path
/// (`a/run`, `b/run`) that no other log shares; the whole path when even that does not tell
/// them apart (`run.csv` and `run.csv.gz` in one folder).
pub fn unique_names(paths: &[PathBuf], stems: &[String]) -> Vec<String> {
    // Folder components of each resolved path, innermost first.
    let folders: Vec<Vec<String>> = paths
        .iter()
        .map(|p| {
            let full = p.canonicalize().unwrap_or_else(|_| p.clone());
            let parent = full.parent().unwrap_or(Path::new("")).to_path_buf();
            parent
                .components()
                .rev()
                .filter_map(|c| match c {
                    Component::Normal(s) => Some(s.to_string_lossy().into_owned()),
                    _ => None,
                })
                .collect()
        })
        .collect();
    let suffix = |i: usize, k: usize| -> String {
        let mut parts: Vec<&str> = folders[i].iter().take(k).map(String::as_str).collect();
        parts.reverse();
        parts.push(&stems[i]);
        parts.join("/")
    };
    (0..paths.len())
        .map(|i| {
            let depth = folders[i].len();
            (0..=depth)
                .map(|k| suffix(i, k))
                .find(|s| {
                    (0..paths.len())
                        .filter(|&j| j != i)
                        .all(|j| (0..=folders[j].len()).all(|k| suffix(j, k) != *s))
                })
                .unwrap_or_else(|| paths[i].display().to_string())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(paths: &[&str]) -> Vec<String> {
        let p: Vec<PathBuf> = paths.iter().map(PathBuf::from).collect();
        let stems: Vec<String> = paths
            .iter()
            .map(|s| {
                Path::new(s).file_name().unwrap().to_string_lossy().split('.').next().unwrap().to_string()
            })
            .collect();
        unique_names(&p, &stems)
    }

    #[test]
    fn shortest_distinguishing_suffix() {
        assert_eq!(names(&["/x/a/run.csv", "/x/b/run.csv"]), ["a/run", "b/run"]);
        assert_eq!(names(&["/x/a/run.csv", "/x/b/hot.csv"]), ["run", "hot"]);
        assert_eq!(names(&["/p/a/run.csv", "/q/a/run.csv", "/q/c.csv"]), ["p/a/run", "q/a/run", "c"]);
        // Same folder, same stem: the whole paths.
        assert_eq!(names(&["/x/run.csv", "/x/run.csv.gz"]), ["/x/run.csv", "/x/run.csv.gz"]);
    }

    #[test]
    fn numbers_and_twins_are_refused() {
        let e = check_paths(&[PathBuf::from("2.0")]).unwrap_err().to_string();
        assert!(e.contains("--huber=2.0"), "{e}");
        let e = check_paths(&[PathBuf::from("no/such.csv"), PathBuf::from("no/such.csv")]).unwrap_err();
        assert!(e.to_string().contains("given twice"), "{e}");
    }
}
