//! How much memory this machine has free: work that would not fit is refused before it
//! starts (readers, generators, seed and step counts), with a message naming the sizes.

/// The memory available to a new allocation (`MemAvailable` of `/proc/meminfo`), where the
/// system says.
pub fn available_bytes() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
