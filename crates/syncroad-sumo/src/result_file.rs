//! Writing a result file: the one writer every table, record, report, plot and script of the
//! workspace goes through.
//!
//! What is at the path decides how it is written:
//! * nothing, or a regular file: the bytes go to a temporary file in the same folder
//!   (tempfile's `NamedTempFile`), which is flushed, synced and renamed over the path, and the
//!   folder is synced; a crash or a full disk leaves the old file or none, never a cut-off one;
//! * a symlink to a regular file: the link's target is replaced the same way, in the target's
//!   folder, and the link stays a link;
//! * a FIFO, a character device (`/dev/stdout`, `/dev/null`, `/dev/full`) or any path under
//!   `/dev` or `/proc`: the bytes are written through to it (opened for appending, never
//!   created or renamed over); a write it refuses (`/dev/full`: no space) is an error naming
//!   the path;
//! * a folder, a block device, a socket or a dangling symlink: refused with an error that says
//!   what is there.
//!
//! Nothing that is not a regular file is ever renamed over.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};

/// Why a result file could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ResultFileError {
    /// Something other than a file is at the path.
    #[error("cannot write {path}: it is {what}; name a file (it is created, or replaced atomically) or a FIFO or character device (written through)")]
    NotAFile {
        /// The path as given.
        path: PathBuf,
        /// What is there.
        what: &'static str,
    },
    /// A symlink whose target does not exist.
    #[error("cannot write {path}: it is a symlink to {target}, which does not exist; create the target or name another file")]
    DanglingLink {
        /// The path as given.
        path: PathBuf,
        /// Where it points.
        target: PathBuf,
    },
    /// The file system refused.
    #[error("cannot write {path}")]
    Io {
        /// The path as given.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The caller's writer failed.
    #[error("cannot write {path}")]
    Write {
        /// The path as given.
        path: PathBuf,
        /// The cause.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// How the path is written.
enum Target {
    /// Replaced atomically: the file's real location (a symlink resolved).
    Replace(PathBuf),
    /// Written through (FIFO, character device, `/dev`, `/proc`).
    Through,
}

fn target(path: &Path) -> Result<Target, ResultFileError> {
    let io = |source| ResultFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    if path.starts_with("/dev") || path.starts_with("/proc") {
        return Ok(Target::Through);
    }
    let link = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(Target::Replace(path.to_path_buf()))
        }
        Err(e) => return Err(io(e)),
    };
    let meta = if link.file_type().is_symlink() {
        match std::fs::metadata(path) {
            Ok(m) => m,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(ResultFileError::DanglingLink {
                    path: path.to_path_buf(),
                    target: std::fs::read_link(path).map_err(io)?,
                })
            }
            Err(e) => return Err(io(e)),
        }
    } else {
        link.clone()
    };
    let t = meta.file_type();
    let refuse = |what| {
        Err(ResultFileError::NotAFile {
            path: path.to_path_buf(),
            what,
        })
    };
    if t.is_file() {
        if link.file_type().is_symlink() {
            return Ok(Target::Replace(std::fs::canonicalize(path).map_err(io)?));
        }
        return Ok(Target::Replace(path.to_path_buf()));
    }
    if t.is_fifo() || t.is_char_device() {
        return Ok(Target::Through);
    }
    if t.is_dir() {
        return refuse("a folder");
    }
    if t.is_block_device() {
        return refuse("a block device");
    }
    if t.is_socket() {
        return refuse("a socket");
    }
    refuse("neither a file nor a device")
}

/// Writes `path` (see the module doc for what is at the path): `write` fills a buffered
/// writer; on any failure a file being replaced is left as it was.
pub fn write_result<E>(
    path: &Path,
    write: impl FnOnce(&mut (dyn Write + Send)) -> Result<(), E>,
) -> Result<(), ResultFileError>
where
    E: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    let io = |source| ResultFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let failed = |e: E| ResultFileError::Write {
        path: path.to_path_buf(),
        source: e.into(),
    };
    match target(path)? {
        Target::Through => {
            let file = OpenOptions::new().append(true).open(path).map_err(io)?;
            let mut w = BufWriter::new(file);
            write(&mut w).map_err(failed)?;
            w.flush().map_err(io)?;
            Ok(())
        }
        Target::Replace(real) => {
            let dir = folder_of(&real);
            let name = real.file_name().unwrap_or_default().to_string_lossy();
            let tmp = builder(&format!(".{name}."), ".tmp")
                .tempfile_in(&dir)
                .map_err(io)?;
            let mut w = BufWriter::new(tmp);
            write(&mut w).map_err(failed)?;
            w.flush().map_err(io)?;
            let tmp = w.into_inner().map_err(|e| io(e.into_error()))?;
            persist(tmp, &real, &dir).map_err(io)
        }
    }
}

/// Writes `path` through a tool that wants a file name (a plotting backend picks its format
/// from the extension): `write` is given a temporary path with the same extension in the same
/// folder, which then replaces `path` as [`write_result`] does (or is copied through to a
/// special file).
pub fn write_result_via_path<E>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<(), ResultFileError>
where
    E: Into<Box<dyn std::error::Error + Send + Sync>>,
{
    let io = |source| ResultFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let failed = |e: E| ResultFileError::Write {
        path: path.to_path_buf(),
        source: e.into(),
    };
    let ext = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    match target(path)? {
        Target::Through => {
            let tmp = tempfile::Builder::new()
                .suffix(&ext)
                .tempfile()
                .map_err(io)?;
            write(tmp.path()).map_err(failed)?;
            let bytes = std::fs::read(tmp.path()).map_err(io)?;
            write_result(path, |w| w.write_all(&bytes))
        }
        Target::Replace(real) => {
            let dir = folder_of(&real);
            let name = real.file_stem().unwrap_or_default().to_string_lossy();
            let tmp = builder(&format!(".{name}."), &ext)
                .tempfile_in(&dir)
                .map_err(io)?;
            write(tmp.path()).map_err(failed)?;
            // The tool wrote through its own handle: reopen to sync what it wrote.
            File::open(tmp.path())
                .and_then(|f| f.sync_all())
                .map_err(io)?;
            persist(tmp, &real, &dir).map_err(io)
        }
    }
}

/// Temporary files with the mode a plain `create` gives (0o666 less the umask), not
/// tempfile's private 0o600: results are read by others.
fn builder<'a>(prefix: &'a str, suffix: &'a str) -> tempfile::Builder<'a, 'a> {
    use std::os::unix::fs::PermissionsExt;
    let mut b = tempfile::Builder::new();
    b.prefix(prefix)
        .suffix(suffix)
        .permissions(std::fs::Permissions::from_mode(0o666));
    b
}

fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Syncs the temporary file, renames it to `real` and syncs the folder, so the new name
/// survives a power cut.
fn persist(tmp: tempfile::NamedTempFile, real: &Path, dir: &Path) -> std::io::Result<()> {
    tmp.as_file().sync_all()?;
    tmp.persist(real).map_err(|e| e.error)?;
    File::open(dir)?.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;

    fn put(path: &Path, text: &str) -> Result<(), ResultFileError> {
        write_result(path, |w| w.write_all(text.as_bytes()))
    }

    #[test]
    fn a_new_or_regular_file_is_replaced_whole_and_leaves_no_temporary_file() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path();
        let p = d.join("r.md");
        put(&p, "one").unwrap();
        put(&p, "two").unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "two");
        // A writer that fails leaves the old file and no temporary file.
        let e = write_result(&p, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk on fire"))
        })
        .unwrap_err();
        assert_eq!(format!("{e}"), format!("cannot write {}", p.display()));
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "two");
        let names: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("r.md")]);
    }

    #[test]
    fn a_symlink_stays_a_link_and_its_target_gets_the_bytes() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path();
        std::fs::create_dir_all(d.join("real")).unwrap();
        let target = d.join("real/report.md");
        std::fs::write(&target, "old").unwrap();
        let link = d.join("link.md");
        symlink(&target, &link).unwrap();
        put(&link, "new").unwrap();
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        // A dangling link is refused and not replaced by a file.
        let dangling = d.join("dangling.md");
        symlink(d.join("nowhere/x.md"), &dangling).unwrap();
        let e = put(&dangling, "x").unwrap_err().to_string();
        assert!(
            e.contains("is a symlink to") && e.contains("does not exist"),
            "{e}"
        );
        assert!(std::fs::symlink_metadata(&dangling)
            .unwrap()
            .file_type()
            .is_symlink());
    }

    #[test]
    fn a_fifo_is_written_through_and_stays_a_fifo() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path();
        let p = d.join("pipe");
        let c = std::ffi::CString::new(p.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let reader = {
            let p = p.clone();
            std::thread::spawn(move || std::fs::read_to_string(p).unwrap())
        };
        put(&p, "through the pipe").unwrap();
        assert_eq!(reader.join().unwrap(), "through the pipe");
        assert!(std::fs::symlink_metadata(&p).unwrap().file_type().is_fifo());
    }

    #[test]
    fn devices_are_written_through_and_a_full_device_is_an_error() {
        put(Path::new("/dev/null"), "nothing").unwrap();
        let e = put(Path::new("/dev/full"), &"x".repeat(100_000)).unwrap_err();
        let chain = format!("{e}: {}", std::error::Error::source(&e).unwrap());
        assert!(chain.starts_with("cannot write /dev/full"), "{chain}");
        assert!(chain.contains("No space left on device"), "{chain}");
        assert!(std::fs::metadata("/dev/full")
            .unwrap()
            .file_type()
            .is_char_device());
    }

    #[test]
    fn a_folder_is_refused() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path();
        let e = put(d, "x").unwrap_err().to_string();
        assert!(e.contains("it is a folder"), "{e}");
        assert!(d.is_dir());
    }

    #[test]
    fn a_tool_that_wants_a_file_name_gets_one_with_the_extension() {
        let t = tempfile::tempdir().unwrap();
        let d = t.path();
        let p = d.join("plot.svg");
        std::fs::write(&p, "old").unwrap();
        write_result_via_path(&p, |tmp: &Path| {
            assert_eq!(tmp.extension().unwrap(), "svg");
            assert_eq!(tmp.parent().unwrap(), d);
            std::fs::write(tmp, "<svg/>")
        })
        .unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "<svg/>");
        assert_eq!(std::fs::read_dir(d).unwrap().count(), 1);
    }
}
