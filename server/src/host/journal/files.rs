//! The files a resume reads back (the journal, its checkpoint) are input, like a scene:
//! opened without waiting (opening a FIFO for reading blocks until a writer comes), taken
//! only if a regular file (a link to `/dev/zero` would be read for ever, a directory is
//! no journal), and read at most a bound.

use std::fs::{File, OpenOptions};
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::Path;

use anyhow::{bail, Context, Result};

/// Opens `path` (a `what`, in errors) for reading if it is a regular file (a link to one
/// is followed), with its size; anything else is refused, naming what it is.
pub fn open_regular(path: &Path, what: &str) -> Result<(File, u64)> {
    // O_NONBLOCK: the open returns at once whatever the file is; a regular file reads
    // the same with it.
    let file = OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .with_context(|| format!("cannot read the {what} {}", path.display()))?;
    let meta = file
        .metadata()
        .with_context(|| format!("cannot read the {what} {}", path.display()))?;
    let kind = meta.file_type();
    if !kind.is_file() {
        let is = if kind.is_dir() {
            "a directory"
        } else if kind.is_fifo() {
            "a FIFO"
        } else if kind.is_char_device() || kind.is_block_device() {
            "a device"
        } else if kind.is_socket() {
            "a socket"
        } else {
            "not a file"
        };
        bail!(
            "the {what} {} is {is}, not a regular file: refused",
            path.display()
        );
    }
    Ok((file, meta.len()))
}

/// Reads the whole of the regular file `path` (a `what`) if it holds at most `max`
/// bytes; a larger one is refused without being read.
pub fn read_bounded(path: &Path, what: &str, max: u64) -> Result<Vec<u8>> {
    use std::io::Read;
    let (file, len) = open_regular(path, what)?;
    if len > max {
        bail!(
            "the {what} {} holds {len} bytes, more than the {max} it may: refused",
            path.display()
        );
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(max + 1)
        .read_to_end(&mut bytes)
        .with_context(|| format!("cannot read the {what} {}", path.display()))?;
    if bytes.len() as u64 > max {
        bail!(
            "the {what} {} grew past the {max} bytes it may while read: refused",
            path.display()
        );
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_fifos_and_directories_are_refused_without_reading_or_waiting() {
        let dir = tempfile::tempdir().unwrap();
        let zero = dir.path().join("zero");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        let e = format!(
            "{:#}",
            read_bounded(&zero, "checkpoint", 1 << 20).unwrap_err()
        );
        assert!(e.contains("a device") && e.contains("zero"), "{e}");
        let fifo = dir.path().join("fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        // No writer: a blocking open would never return.
        let e = format!("{:#}", open_regular(&fifo, "journal").unwrap_err());
        assert!(e.contains("a FIFO"), "{e}");
        let e = format!("{:#}", open_regular(dir.path(), "journal").unwrap_err());
        assert!(e.contains("a directory"), "{e}");
        let big = dir.path().join("big");
        std::fs::write(&big, vec![7u8; 4096]).unwrap();
        let e = format!("{:#}", read_bounded(&big, "checkpoint", 4095).unwrap_err());
        assert!(e.contains("4096 bytes"), "{e}");
        assert_eq!(read_bounded(&big, "checkpoint", 4096).unwrap().len(), 4096);
    }
}
