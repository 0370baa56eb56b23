//! Every file a user hands the project is opened here (issue 28, "hostile input at every entry
//! point"): scene loaders, sweep files, `verify` case folders, `check --replay` folders and
//! `report --run` manifests all read through these functions, never through `std::fs::read*`.
//!
//! Contract:
//! - **Regular files only.** Anything that is not a regular file after resolving links (a FIFO,
//!   a socket, a device such as `/dev/zero` or a link to one, a folder) is refused before it is
//!   opened, naming the file: opening a FIFO blocks until a writer comes, and a device never ends.
//! - **A size limit per kind, checked before reading.** The caller passes the limit that fits the
//!   kind of file (a scene TOML is not 100 MB; each kind's constant lives beside its parser and
//!   the README's "Bad input" section lists them all). The file's size is checked against it
//!   from its metadata before a byte is read, and the read itself is capped at `limit + 1`
//!   bytes, so a file that grows while it is read cannot exceed it either. The error states the
//!   size and the limit.
//! - **Text is UTF-8** ([`read_text_limited`]): other bytes are an error naming the file and the
//!   byte offset, never a lossy conversion.
//! - Every error is an [`InputError`] whose `file` is the path as given (so a chain through a
//!   case or sweep folder names the file the user can find).
//!
//! Rejected design: checking only the size from metadata. `/proc` files and files that grow
//! report a size that is not what a read returns; the capped read is what bounds memory, the
//! metadata check is what lets a huge file be refused without reading it.

use std::io::Read;
use std::path::Path;

use crate::InputError;

fn label(path: &Path) -> String {
    path.display().to_string()
}

/// `bytes` as the error text shows a size: exact bytes, and MiB/GiB beside large ones.
pub fn size_text(bytes: u64) -> String {
    const MIB: u64 = 1 << 20;
    if bytes >= 1 << 30 {
        format!("{bytes} bytes ({:.1} GiB)", bytes as f64 / (1u64 << 30) as f64)
    } else if bytes >= MIB {
        format!("{bytes} bytes ({:.1} MiB)", bytes as f64 / MIB as f64)
    } else {
        format!("{bytes} bytes")
    }
}

fn cannot_read(path: &Path, e: &std::io::Error) -> InputError {
    let file = label(path);
    InputError::new(&file, "file", &file, format!("cannot be read: {e}"))
}

/// Refuses anything but a regular file, after resolving links, and returns its size. Checked
/// before the file is opened.
pub fn regular_file(path: &Path) -> Result<u64, InputError> {
    let file = label(path);
    let meta = std::fs::metadata(path).map_err(|e| cannot_read(path, &e))?;
    if meta.is_file() {
        return Ok(meta.len());
    }
    let kind = if meta.is_dir() {
        "a folder"
    } else {
        "a special file (a FIFO, socket or device)"
    };
    Err(InputError::new(
        &file,
        "file",
        &file,
        format!("is {kind}, not a regular file (after resolving links)"),
    ))
}

fn too_large(path: &Path, size: Option<u64>, limit: u64) -> InputError {
    let file = label(path);
    let value = match size {
        Some(size) => size_text(size),
        None => format!("more than {}", size_text(limit)),
    };
    InputError::new(
        &file,
        "file size",
        value,
        format!(
            "is over the limit of {} for this kind of file",
            size_text(limit)
        ),
    )
}

/// Opens a regular file ([`regular_file`]) of at most `limit` bytes, returning it and its size;
/// the caller streams it (through `Read::take(limit + 1)` or a record limit of its own).
pub fn open_limited(path: &Path, limit: u64) -> Result<(std::fs::File, u64), InputError> {
    let size = regular_file(path)?;
    if size > limit {
        return Err(too_large(path, Some(size), limit));
    }
    let f = std::fs::File::open(path).map_err(|e| cannot_read(path, &e))?;
    Ok((f, size))
}

/// Reads a whole regular file of at most `limit` bytes (see the module's contract).
pub fn read_limited(path: &Path, limit: u64) -> Result<Vec<u8>, InputError> {
    let (f, size) = open_limited(path, limit)?;
    let mut bytes = Vec::with_capacity(size.min(limit) as usize);
    f.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| cannot_read(path, &e))?;
    if bytes.len() as u64 > limit {
        return Err(too_large(path, None, limit));
    }
    Ok(bytes)
}

/// Reads a whole regular UTF-8 text file of at most `limit` bytes; bytes that are not UTF-8 are
/// an error naming the byte offset.
pub fn read_text_limited(path: &Path, limit: u64) -> Result<String, InputError> {
    let bytes = read_limited(path, limit)?;
    String::from_utf8(bytes).map_err(|e| {
        let file = label(path);
        let at = e.utf8_error().valid_up_to();
        InputError::new(
            &file,
            format!("byte {at}"),
            format!("{:#04x}", e.as_bytes()[at]),
            "is not UTF-8 text",
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("forestlod-files-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn limits_are_checked_before_reading_and_stated() {
        let dir = temp_dir("limits");
        let p = dir.join("a.toml");
        std::fs::write(&p, vec![b'x'; 2048]).unwrap();
        assert_eq!(read_limited(&p, 2048).unwrap().len(), 2048);
        let e = read_limited(&p, 2047).unwrap_err().to_string();
        assert!(e.contains("2048 bytes") && e.contains("limit of 2047 bytes"), "{e}");
        assert!(e.starts_with(&p.display().to_string()), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn devices_folders_and_links_to_them_are_refused() {
        let dir = temp_dir("special");
        let e = read_limited(Path::new("/dev/zero"), 10).unwrap_err().to_string();
        assert!(e.contains("/dev/zero") && e.contains("special file"), "{e}");
        #[cfg(unix)]
        {
            let link = dir.join("zero.csv");
            std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
            let e = read_limited(&link, 10).unwrap_err().to_string();
            assert!(e.contains("zero.csv") && e.contains("special file"), "{e}");
        }
        let e = read_limited(&dir, 10).unwrap_err().to_string();
        assert!(e.contains("a folder"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn text_must_be_utf8_naming_the_offset() {
        let dir = temp_dir("utf8");
        let p = dir.join("s.toml");
        std::fs::write(&p, b"ab\xffc").unwrap();
        let e = read_text_limited(&p, 100).unwrap_err().to_string();
        assert!(e.contains("byte 2") && e.contains("0xff"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
