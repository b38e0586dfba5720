//! File locks (flock): the address-block lock that deployments starting at once share, and
//! each deployment's own lock, held by its supervisor for its whole life — whoever can take it
//! knows that no supervisor of that deployment runs, whatever pid files say.

use std::fs::{File, OpenOptions};
use std::io;
use std::os::fd::AsRawFd;
use std::path::Path;

/// An exclusive lock on a file, released when dropped (or when its process ends).
pub struct Lock {
    /// Held open: closing it lets the lock go.
    _file: File,
}

fn open(path: &Path) -> io::Result<File> {
    OpenOptions::new().create(true).truncate(false).write(true).open(path)
}

impl Lock {
    /// Waits for the lock.
    pub fn take(path: &Path) -> io::Result<Lock> {
        let file = open(path)?;
        // SAFETY: flock on a descriptor this value owns.
        if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX) } != 0 {
            return Err(io::Error::last_os_error());
        }
        Ok(Lock { _file: file })
    }

    /// The lock if nobody holds it, `None` if somebody does. The file is made if it is not
    /// there. A lock taken on a file its holder removed meanwhile ([`Lock::remove`]) is no lock:
    /// the path is opened again, so that two takers never hold two different files.
    pub fn try_take(path: &Path) -> io::Result<Option<Lock>> {
        loop {
            let file = open(path)?;
            // SAFETY: as in `take`.
            if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
                let e = io::Error::last_os_error();
                return if e.raw_os_error() == Some(libc::EWOULDBLOCK) { Ok(None) } else { Err(e) };
            }
            if same_file(&file, path)? {
                return Ok(Some(Lock { _file: file }));
            }
        }
    }

    /// Whether somebody holds the lock at `path`; a missing file is a free lock (and stays
    /// missing).
    pub fn is_held(path: &Path) -> io::Result<bool> {
        let file = match OpenOptions::new().write(true).open(path) {
            Ok(f) => f,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(false),
            Err(e) => return Err(e),
        };
        // SAFETY: as in `take`; the lock taken here goes when `file` closes.
        if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } == 0 {
            return Ok(false);
        }
        let e = io::Error::last_os_error();
        if e.raw_os_error() == Some(libc::EWOULDBLOCK) { Ok(true) } else { Err(e) }
    }

    /// Removes the lock's file, then lets the lock go: whoever waited on the old file finds it
    /// gone from its path and opens the path again (see [`Lock::try_take`]).
    pub fn remove(self, path: &Path) -> io::Result<()> {
        std::fs::remove_file(path)
    }
}

/// Whether `file` is still the file at `path`.
fn same_file(file: &File, path: &Path) -> io::Result<bool> {
    use std::os::unix::fs::MetadataExt;
    let held = file.metadata()?;
    match std::fs::metadata(path) {
        Ok(there) => Ok((there.dev(), there.ino()) == (held.dev(), held.ino())),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(false),
        Err(e) => Err(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_lock_is_not_taken_twice() {
        let dir = tempfile::tempdir().expect("a temp dir");
        let path = dir.path().join("lock");
        let held = Lock::try_take(&path).expect("opens").expect("free");
        assert!(Lock::try_take(&path).expect("opens").is_none(), "held");
        drop(held);
        assert!(Lock::try_take(&path).expect("opens").is_some(), "free again");
    }

    #[test]
    fn a_removed_lock_is_free_and_its_file_gone() {
        let dir = tempfile::tempdir().expect("a temp dir");
        let path = dir.path().join("lock");
        let held = Lock::try_take(&path).expect("opens").expect("free");
        assert!(Lock::is_held(&path).expect("probes"));
        held.remove(&path).expect("removes");
        assert!(!Lock::is_held(&path).expect("probes") && !path.exists(), "free, and the probe made no file");
    }
}
