//! One writer per output folder: an advisory lock (`flock`, through std's `File::try_lock`)
//! on `DIR/.syncroad.lock`, held while a command writes into `DIR` (run, simulate, compare, map, sweep, collect).
//!
//! The kernel releases the lock when the holding process ends, however it ends (a normal
//! exit, an error, Ctrl-C, SIGKILL), so a stale lock file never blocks anyone; the file keeps
//! the holder's pid and command line, which a refused second writer names.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::Path;

use anyhow::Context;

use crate::error::InputError;

/// The lock file's name inside the folder.
pub const LOCK_FILE: &str = ".syncroad.lock";

/// The held lock: released when dropped (or when the process ends).
#[derive(Debug)]
pub struct FolderLock {
    _file: File,
}

/// Takes the lock on `dir` (created if missing), given as `flag` for errors; refuses with the
/// holder's pid and command when another process holds it.
pub fn hold(flag: &str, dir: &Path) -> anyhow::Result<FolderLock> {
    std::fs::create_dir_all(dir).map_err(|e| crate::error::folder_error(flag, dir, e))?;
    let path = dir.join(LOCK_FILE);
    // The lock is a regular file of the folder's own: a link (which would lock, and write our
    // pid into, whatever it points to), a FIFO or a device there is refused, not followed.
    let not_regular = |what: &str| {
        InputError::new(format!(
            "{flag} = {}: {} is {what}, not the regular lock file syncroad keeps there; remove it or give another {flag}",
            dir.display(),
            path.display()
        ))
    };
    if let Ok(meta) = std::fs::symlink_metadata(&path) {
        let t = meta.file_type();
        if t.is_symlink() {
            return Err(not_regular("a symbolic link").into());
        }
        if !t.is_file() {
            return Err(not_regular("a folder, FIFO, socket or device").into());
        }
    }
    let mut file = {
        use std::os::unix::fs::OpenOptionsExt;
        OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
            .open(&path)
    }
    .map_err(|e| match e.raw_os_error() {
        Some(libc::ELOOP) => not_regular("a symbolic link").into(),
        _ => anyhow::Error::new(e).context(format!(
            "{flag} = {}: cannot open {}",
            dir.display(),
            path.display()
        )),
    })?;
    if !file.metadata().map(|m| m.is_file()).unwrap_or(false) {
        return Err(not_regular("not a regular file").into());
    }
    match file.try_lock() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => {
            let mut holder = String::new();
            let _ = file.read_to_string(&mut holder);
            let holder = holder.trim();
            let who = if holder.is_empty() {
                "a process that has not written its name yet".to_string()
            } else {
                holder.replace('\n', ": ")
            };
            return Err(InputError::new(format!(
                "{flag} = {}: another syncroad is writing this folder (pid {who}); wait for it to end, or give another {flag}",
                dir.display()
            ))
            .into());
        }
        Err(TryLockError::Error(e)) => {
            return Err(anyhow::Error::new(e).context(format!(
                "{flag} = {}: cannot lock {}",
                dir.display(),
                path.display()
            )))
        }
    }
    let args: Vec<String> = std::env::args().collect();
    let command =
        shlex::try_join(args.iter().map(String::as_str)).unwrap_or_else(|_| args.join(" "));
    let stamp = format!("{}\n{command}\n", std::process::id());
    file.set_len(0)
        .and_then(|()| file.rewind())
        .and_then(|()| file.write_all(stamp.as_bytes()))
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(FolderLock { _file: file })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_holder_is_refused_naming_the_first_and_a_dropped_lock_is_free() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path().join("out");
        let first = hold("--out", &d).unwrap();
        // flock locks belong to the open file: a second open in the same process conflicts
        // as another process would.
        let e = hold("--out", &d).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!(
                "--out = {}: another syncroad is writing this folder (pid {}: ",
                d.display(),
                std::process::id()
            )),
            "{e}"
        );
        drop(first);
        hold("--out", &d).unwrap();
        assert!(d.join(LOCK_FILE).is_file());
    }
}
