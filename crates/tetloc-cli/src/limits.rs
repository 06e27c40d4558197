//! Work and outputs bounded before they start: counts whose arrays cannot fit in memory, and
//! outputs larger than the free disk, are refused with a message that names the limit
//! (instead of an allocation failure, an OOM kill or a full disk hours later).

use anyhow::{bail, Result};
use std::path::Path;

fn gb(bytes: u128) -> String {
    format!("{:.1} GB", bytes as f64 / 1e9)
}

/// Refuses `count` items of `bytes_each` bytes (`what` says what they are) when they need
/// more memory than this process may take (`tetloc_core::memory`; unchecked off Linux).
pub fn check_memory(what: &str, count: u128, bytes_each: u128) -> Result<()> {
    Ok(tetloc_core::memory::check(count.saturating_mul(bytes_each), || what.to_string())?)
}

/// Bytes free for an unprivileged user on the file system of `dir`, if known.
pub fn free_disk_bytes(dir: &Path) -> Option<u64> {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
        // SAFETY: `c` is a NUL-terminated path and `st` a plain struct that statvfs fills.
        let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
        // SAFETY: both pointers are valid for the call.
        if unsafe { libc::statvfs(c.as_ptr(), &mut st) } != 0 {
            return None;
        }
        let free = st.f_bavail as u128 * st.f_frsize as u128;
        Some(u64::try_from(free).unwrap_or(u64::MAX))
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        None
    }
}

/// Refuses an output of `bytes` bytes (at least) at `path` when its file system has less room.
pub fn check_disk(path: &Path, bytes: u128) -> Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if let Some(free) = free_disk_bytes(dir) {
        if bytes > free as u128 {
            bail!(
                "{}: the output takes at least {}, and {} has {} free",
                path.display(),
                gb(bytes),
                dir.display(),
                gb(free as u128)
            );
        }
    }
    Ok(())
}
