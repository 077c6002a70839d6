//! The one way syncroad reads a file the user names for SUMO (network, configuration, route
//! and additional files): it must be a regular file. A FIFO, a device or a socket never ends
//! (reading one hung a run before it started), and SUMO reads every input to its end, so
//! anything else is refused with what it is.

use std::io::Read;
use std::path::Path;

/// What `path` is when it is not a regular file (`a FIFO`, `a folder`, …); `None` for a
/// regular file (symbolic links followed) or a path that does not exist (the caller says
/// "not found" in its own terms).
pub fn not_regular(path: &Path) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let t = std::fs::metadata(path).ok()?.file_type();
    if t.is_file() {
        None
    } else if t.is_dir() {
        Some("a folder")
    } else if t.is_fifo() {
        Some("a FIFO (named pipe)")
    } else if t.is_socket() {
        Some("a socket")
    } else if t.is_char_device() || t.is_block_device() {
        Some("a device")
    } else {
        Some("not a regular file")
    }
}

/// Reads a regular file as text; `limit` bytes at most when given (`Ok(None)` beyond it).
/// Errors are the reason, for the caller's message.
pub fn read_text(path: &Path, limit: Option<u64>) -> Result<Option<String>, String> {
    if let Some(what) = not_regular(path) {
        return Err(format!(
            "{what}, not a regular file: SUMO reads its input files to their end; give a file"
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => "file not found".to_string(),
        _ => e.to_string(),
    })?;
    let mut text = String::new();
    match limit {
        None => {
            let mut f = file;
            f.read_to_string(&mut text).map_err(|e| e.to_string())?;
        }
        Some(max) => {
            file.take(max + 1)
                .read_to_string(&mut text)
                .map_err(|e| e.to_string())?;
            if text.len() as u64 > max {
                return Ok(None);
            }
        }
    }
    Ok(Some(text))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("net.xml");
        std::fs::write(&file, "<net/>").unwrap();
        assert_eq!(read_text(&file, None).unwrap().as_deref(), Some("<net/>"));
        assert_eq!(read_text(&file, Some(3)).unwrap(), None, "beyond the limit");
        assert_eq!(not_regular(&file), None);
        let fifo = dir.path().join("fifo.xml");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: mkfifo on a path in our own temporary folder.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        // Refused without opening it (opening a FIFO for reading blocks until a writer comes).
        let e = read_text(&fifo, None).unwrap_err();
        assert!(
            e.starts_with("a FIFO (named pipe), not a regular file"),
            "{e}"
        );
        assert_eq!(not_regular(dir.path()), Some("a folder"));
        assert_eq!(not_regular(Path::new("/dev/null")), Some("a device"));
        let missing = read_text(&dir.path().join("missing.xml"), None).unwrap_err();
        assert_eq!(missing, "file not found");
    }
}
