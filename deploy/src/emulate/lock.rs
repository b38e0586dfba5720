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

    /// The lock if nobody holds it, `None` if somebody does.
    pub fn try_take(path: &Path) -> io::Result<Option<Lock>> {
        let file = open(path)?;
        // SAFETY: as in `take`.
        if unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } == 0 {
            return Ok(Some(Lock { _file: file }));
        }
        let e = io::Error::last_os_error();
        if e.raw_os_error() == Some(libc::EWOULDBLOCK) { Ok(None) } else { Err(e) }
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
}
