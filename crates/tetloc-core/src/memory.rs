//! How much memory this process may still take: work that would not fit is refused before it
//! starts (readers, generators, seed and step counts), with a message naming the sizes.
//!
//! The machine's free memory is not the whole answer. A batch job (Slurm, Kubernetes, a
//! container) runs in a cgroup whose limit is far below the node's memory, and `ulimit -v`
//! caps the address space: past either, an allocation is refused (an abort) or the process is
//! killed, with no message. So the least of the three headrooms is what is available.

use std::path::{Path, PathBuf};

/// Bytes this process may still allocate, where the system says (Linux): the least of
/// `MemAvailable` (`/proc/meminfo`), the room left under each memory cgroup limit above it
/// (v1 or v2) and the room left under its address-space and data limits (`ulimit -v`, `-d`).
pub fn available_bytes() -> Option<u64> {
    let read = |p: &Path| std::fs::read_to_string(p).ok();
    let machine = read(Path::new("/proc/meminfo")).and_then(|m| meminfo_available(&m));
    let cgroup = match (read(Path::new("/proc/self/mountinfo")), read(Path::new("/proc/self/cgroup"))) {
        (Some(mounts), Some(groups)) => cgroup_headroom(&mounts, &groups, &read),
        _ => None,
    };
    let limits = match (read(Path::new("/proc/self/limits")), read(Path::new("/proc/self/status"))) {
        (Some(limits), Some(status)) => rlimit_headroom(&limits, &status),
        _ => None,
    };
    [machine, cgroup, limits].into_iter().flatten().min()
}

/// Refuses work that needs `need` bytes where fewer are available ([`available_bytes`];
/// unchecked where the system does not say), `what` naming it (called only to refuse).
pub fn check(need: u128, what: impl FnOnce() -> String) -> crate::Result<()> {
    match available_bytes().filter(|&a| need > u128::from(a)) {
        Some(available) => Err(crate::Error::OutOfMemory { what: what(), need, available }),
        None => Ok(()),
    }
}

/// `MemAvailable` of a `/proc/meminfo`, in bytes.
fn meminfo_available(meminfo: &str) -> Option<u64> {
    kib_field(meminfo, "MemAvailable:")
}

/// The kibibytes of the line of `text` that starts with `key` (`/proc` files), in bytes.
fn kib_field(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    let kib: u64 = line[key.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// A limit of `/proc/self/limits` (`Max address space`...): its soft value, `None` when
/// unlimited.
fn soft_limit(limits: &str, name: &str) -> Option<u64> {
    let line = limits.lines().find(|l| l.starts_with(name))?;
    line[name.len()..].split_whitespace().next()?.parse().ok()
}

/// The room left under the address-space limit (against `VmSize`) and the data limit
/// (against `VmData`) of a process's `/proc/self/limits` and `/proc/self/status`.
fn rlimit_headroom(limits: &str, status: &str) -> Option<u64> {
    let room = |limit: &str, used: &str| Some(soft_limit(limits, limit)?.saturating_sub(kib_field(status, used)?));
    [room("Max address space", "VmSize:"), room("Max data size", "VmData:")].into_iter().flatten().min()
}

/// Limits at or above this are cgroup v1's "unlimited" (2^63 rounded down to a page).
const NO_V1_LIMIT: u64 = 1 << 62;

/// The least room left under the memory limits of this process's cgroup and its ancestors,
/// given `/proc/self/mountinfo`, `/proc/self/cgroup` and a reader of the cgroup files. The
/// room of a level is its limit less its usage, the file cache not counted (the kernel
/// reclaims it before it fails an allocation: a file read twice must not shrink the room).
/// `None` when no level sets a limit (or no memory cgroup is mounted).
fn cgroup_headroom(mountinfo: &str, cgroup: &str, read: &dyn Fn(&Path) -> Option<String>) -> Option<u64> {
    let (dir, top, v2) = cgroup_dir(mountinfo, cgroup)?;
    let number = |dir: &Path, file: &str| read(&dir.join(file))?.trim().parse::<u64>().ok();
    // The file cache of a level's `memory.stat` (v1's hierarchical totals where given).
    let cache = |dir: &Path| {
        let stat = read(&dir.join("memory.stat")).unwrap_or_default();
        let key = |k: &str| stat.lines().find_map(|l| l.strip_prefix(k)?.trim().parse::<u64>().ok());
        let total = |k: &str| if v2 { key(k) } else { key(&format!("total_{k}")).or_else(|| key(k)) };
        total("inactive_file ").unwrap_or(0).saturating_add(total("active_file ").unwrap_or(0))
    };
    let mut least: Option<u64> = None;
    let mut at = Some(dir.as_path());
    while let Some(d) = at.filter(|d| d.starts_with(&top)) {
        // v2's "max" (no limit) does not parse.
        let (limit, usage) = match v2 {
            true => (number(d, "memory.max"), number(d, "memory.current")),
            false => {
                (number(d, "memory.limit_in_bytes").filter(|&l| l < NO_V1_LIMIT), number(d, "memory.usage_in_bytes"))
            }
        };
        let room = limit.zip(usage).map(|(max, used)| max.saturating_sub(used.saturating_sub(cache(d))));
        least = match (least, room) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        at = d.parent();
    }
    least
}

/// The folder of this process's memory cgroup, the mount point above which no level is
/// read, and whether it is cgroup v2: the v1 hierarchy with the memory controller where
/// one is mounted, else the unified (v2) one. A mount whose root is not the process's path
/// (a container's view) is taken relative to that root.
fn cgroup_dir(mountinfo: &str, cgroup: &str) -> Option<(PathBuf, PathBuf, bool)> {
    // /proc/self/cgroup: "ID:CONTROLLERS:PATH"; v2's line is "0::PATH".
    let path_of = |v2: bool| {
        cgroup.lines().find_map(|l| {
            let mut parts = l.splitn(3, ':');
            let (_, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
            let ours = if v2 { controllers.is_empty() } else { controllers.split(',').any(|c| c == "memory") };
            ours.then(|| path.to_string())
        })
    };
    // mountinfo: "ID PARENT MAJ:MIN ROOT MOUNT_POINT OPTIONS [OPTIONAL...] - TYPE SOURCE SUPER".
    let mount_of = |v2: bool| {
        mountinfo.lines().find_map(|l| {
            let (left, right) = l.split_once(" - ")?;
            let fields: Vec<&str> = left.split(' ').collect();
            let mut rest = right.split(' ');
            let (kind, _, options) = (rest.next()?, rest.next()?, rest.next().unwrap_or(""));
            let ours =
                if v2 { kind == "cgroup2" } else { kind == "cgroup" && options.split(',').any(|o| o == "memory") };
            let (root, point) = (fields.get(3)?, fields.get(4)?);
            ours.then(|| (root.to_string(), PathBuf::from(unescape(point))))
        })
    };
    [false, true].into_iter().find_map(|v2| {
        let (path, (root, point)) = (path_of(v2)?, mount_of(v2)?);
        let inside = Path::new(&path).strip_prefix(&root).ok()?;
        Some((point.join(inside), point, v2))
    })
}

/// A mountinfo path with its octal escapes (`\040` for a space) decoded.
fn unescape(s: &str) -> String {
    let b = s.as_bytes();
    let (mut out, mut i) = (Vec::with_capacity(b.len()), 0);
    while i < b.len() {
        let code = (b[i] == b'\\' && i + 3 < b.len())
            .then(|| std::str::from_utf8(&b[i + 1..i + 4]).ok().and_then(|o| u8::from_str_radix(o, 8).ok()))
            .flatten();
        match code {
            Some(c) => {
                out.push(c);
                i += 4;
            }
            None => {
                out.push(b[i]);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    const GIB: u64 = 1 << 30;

    fn files(entries: &[(&str, String)]) -> impl Fn(&Path) -> Option<String> {
        let map: HashMap<PathBuf, String> = entries.iter().map(|(p, s)| (PathBuf::from(p), s.clone())).collect();
        move |p: &Path| map.get(p).cloned()
    }

    /// A v1 memory hierarchy as Slurm nodes mount it: the job's limit (2 GiB, 1.5 GiB used
    /// of which 0.25 GiB file cache, counted by the hierarchy's totals) applies, and the
    /// parent's unlimited value (2^63 rounded to a page) does not.
    #[test]
    fn cgroup_v1_limits_count_the_working_set() {
        let mounts = "35 31 0:32 / /sys/fs/cgroup/memory rw,relatime - cgroup cgroup rw,memory\n\
                      41 31 0:38 / /sys/fs/cgroup/unified rw,relatime - cgroup2 cgroup2 rw\n";
        let groups = "4:memory:/slurm/job_7\n0::/\n";
        let job = "/sys/fs/cgroup/memory/slurm/job_7";
        let read = files(&[
            (&format!("{job}/memory.limit_in_bytes"), format!("{}\n", 2 * GIB)),
            (&format!("{job}/memory.usage_in_bytes"), format!("{}\n", 3 * GIB / 2)),
            (
                &format!("{job}/memory.stat"),
                format!("inactive_file 9\ntotal_inactive_file {}\ntotal_active_file {}\n", GIB / 8, GIB / 8),
            ),
            ("/sys/fs/cgroup/memory/slurm/memory.limit_in_bytes", "9223372036854771712\n".into()),
            ("/sys/fs/cgroup/memory/slurm/memory.usage_in_bytes", format!("{}\n", 40 * GIB)),
        ]);
        assert_eq!(cgroup_headroom(mounts, groups, &read), Some(2 * GIB - (3 * GIB / 2 - GIB / 4)));
        // Unlimited everywhere (this machine's own layout): no cgroup bound.
        let read = files(&[(&format!("{job}/memory.limit_in_bytes"), "9223372036854771712\n".into())]);
        assert_eq!(cgroup_headroom(mounts, groups, &read), None);
    }

    /// cgroup v2: the least room over the levels up to the mount (a parent's limit binds
    /// when it is the smaller), "max" meaning none; a container that sees its own cgroup as
    /// the root ("0::/" under a mount whose root is the container's path) reads the mount's
    /// own files; usage past the limit leaves no room.
    #[test]
    fn cgroup_v2_takes_the_least_room_of_every_level() {
        let mounts = "30 23 0:26 / /sys/fs/cgroup rw,nosuid - cgroup2 cgroup2 rw,nsdelegate\n";
        let groups = "0::/user.slice/job.scope\n";
        let read = files(&[
            ("/sys/fs/cgroup/user.slice/job.scope/memory.max", "max\n".into()),
            ("/sys/fs/cgroup/user.slice/job.scope/memory.current", format!("{}\n", GIB)),
            ("/sys/fs/cgroup/user.slice/memory.max", format!("{}\n", 4 * GIB)),
            ("/sys/fs/cgroup/user.slice/memory.current", format!("{}\n", 3 * GIB)),
            (
                "/sys/fs/cgroup/user.slice/memory.stat",
                format!("anon 5\nactive_file {}\ninactive_file {}\n", GIB / 4, GIB / 4),
            ),
        ]);
        assert_eq!(cgroup_headroom(mounts, groups, &read), Some(4 * GIB - (3 * GIB - GIB / 2)));
        let mounts = "30 23 0:26 /kubepods/pod1 /sys/fs/cgroup rw - cgroup2 cgroup2 rw\n";
        let read = files(&[
            ("/sys/fs/cgroup/memory.max", format!("{}\n", GIB)),
            ("/sys/fs/cgroup/memory.current", format!("{}\n", 2 * GIB)),
        ]);
        assert_eq!(cgroup_headroom(mounts, "0::/kubepods/pod1\n", &read), Some(0));
        assert_eq!(cgroup_headroom(mounts, "0::/elsewhere\n", &read), None, "a path outside the mount's root");
        assert_eq!(cgroup_headroom("", groups, &read), None, "no cgroup mounted");
    }

    /// `ulimit -v` and `ulimit -d` as /proc shows them: the room under the address-space
    /// limit less the process's size, or under the data limit less its data, the smaller.
    #[test]
    fn address_space_and_data_limits_leave_their_room() {
        let limits = "Limit                     Soft Limit           Hard Limit           Units     \n\
                      Max data size             unlimited            unlimited            bytes     \n\
                      Max address space         2147483648           unlimited            bytes     \n";
        let status = "Name:\ttetloc\nVmSize:\t  524288 kB\nVmData:\t  100 kB\n";
        assert_eq!(rlimit_headroom(limits, status), Some(2 * GIB - GIB / 2));
        let limits = limits.replace("Max data size             unlimited", "Max data size             1073741824");
        assert_eq!(rlimit_headroom(&limits, status), Some(GIB - 100 * 1024));
        let unlimited = limits.replace("1073741824", "unlimited").replace("2147483648", "unlimited");
        assert_eq!(rlimit_headroom(&unlimited, status), None);
        let over = limits.replace("2147483648", "1000");
        assert_eq!(rlimit_headroom(&over, status), Some(0));
    }

    #[test]
    fn meminfo_and_mount_paths_parse() {
        assert_eq!(meminfo_available("MemTotal: 8 kB\nMemAvailable:   3 kB\n"), Some(3072));
        assert_eq!(meminfo_available("MemTotal: 8 kB\n"), None);
        assert_eq!(unescape(r"/mnt/with\040space"), "/mnt/with space");
        assert_eq!(unescape(r"/ends\04"), r"/ends\04");
    }

    /// This machine's own files (Linux) give an answer, and some room: its cgroup and limit
    /// files parse, whatever their layout.
    #[cfg(target_os = "linux")]
    #[test]
    fn this_machines_files_give_some_room() {
        let avail = available_bytes().expect("Linux says");
        assert!(avail > 0);
    }
}
