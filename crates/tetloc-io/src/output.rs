//! Outputs that are either complete or absent.
//!
//! Every file tetloc writes goes through an [`AtomicFile`]: a temporary file in the target's
//! directory, written, flushed to disk and renamed over the target on [`AtomicFile::commit`].
//! A failure (full disk, a kill, an error) leaves the previous file intact and no partial one.
//! Commands check their output paths with [`check_output`] and [`check_distinct`] before any
//! work starts, so that a bad path or an output that is also an input costs nothing.
//!
//! Temporaries are registered while they live, so that a program's signal handler can remove
//! them ([`remove_temporaries`]). A process killed outright (SIGKILL, power loss) can leave
//! its temporary file behind, named `.NAME.XXXXXX.tmp` next to NAME (never a partial NAME);
//! [`stale_temporaries`] finds them.
//!
//! Outputs that belong together (the files of `--time-step all` and their `.pvd`) are written
//! in an [`OutputSet`]: each file is finished under its temporary name, and all of them are
//! renamed into place only once the last is written, so a failed step leaves the previous
//! set as it was.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};
use tempfile::NamedTempFile;
use tetloc_core::error::{Error, Result};

/// The temporaries (files and folders) of outputs being written.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A temporary path listed for [`remove_temporaries`] while this lives.
pub struct Registered(PathBuf);

impl Registered {
    /// Creates a temporary (`create`, whose result's path is `path`) and lists it, in one step
    /// for the signal handler: [`remove_temporaries_then_exit`] waits for the list, so it never
    /// runs between the temporary's creation and its listing (which would leave it behind).
    /// `create` must not panic: the panic hook waits for the list too.
    pub fn create<T>(
        create: impl FnOnce() -> std::io::Result<T>,
        path: impl Fn(&T) -> &Path,
    ) -> std::io::Result<(T, Registered)> {
        let mut list = TEMPORARIES.lock().unwrap_or_else(PoisonError::into_inner);
        let made = create()?;
        let at = path(&made).to_path_buf();
        list.push(at.clone());
        Ok((made, Registered(at)))
    }
}

impl Drop for Registered {
    fn drop(&mut self) {
        let mut list = TEMPORARIES.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(k) = list.iter().rposition(|p| *p == self.0) {
            list.swap_remove(k);
        }
    }
}

/// The files an open [`OutputSet`] holds: each one's temporary (registered) and its target.
static STAGED: Mutex<Option<Vec<(Registered, PathBuf)>>> = Mutex::new(None);

/// Outputs that appear together or not at all. While a set is open, an [`AtomicFile`]
/// committed anywhere in the process is flushed and synced under its temporary name and kept
/// there (still registered, so that a signal removes it); [`OutputSet::commit`] then renames
/// them all over their targets, in the order they were committed. A set dropped without
/// `commit` (an error in a later file) removes what it holds: every target stays as it was.
/// A set opened while another is open adds to that one, which commits.
#[must_use = "an OutputSet's files reach their targets only by commit()"]
pub struct OutputSet {
    owner: bool,
}

impl OutputSet {
    pub fn begin() -> OutputSet {
        let mut staged = STAGED.lock().unwrap_or_else(PoisonError::into_inner);
        let owner = staged.is_none();
        if owner {
            *staged = Some(Vec::new());
        }
        OutputSet { owner }
    }

    /// Renames every file of the set over its target. A crash during the renames leaves some
    /// targets new and others old: a caller whose set has an index removes the old index
    /// first ([`OutputSet::commit_after`]).
    pub fn commit(self) -> Result<()> {
        self.commit_after(|| Ok(()))
    }

    /// [`Self::commit`] once `first` has run (nothing is renamed if it fails).
    pub fn commit_after(mut self, first: impl FnOnce() -> Result<()>) -> Result<()> {
        if !self.owner {
            return first();
        }
        self.owner = false;
        let files = STAGED.lock().unwrap_or_else(PoisonError::into_inner).take().unwrap_or_default();
        let mut files = files.into_iter();
        let renamed = first().and_then(|()| {
            let mut dirs: Vec<PathBuf> = Vec::new();
            for (tmp, target) in files.by_ref() {
                std::fs::rename(&tmp.0, &target).map_err(|e| Error::io(&target, e))?;
                let dir = parent_dir(&target).to_path_buf();
                if !dirs.contains(&dir) {
                    dirs.push(dir);
                }
            }
            // The renames reach the disk with their directories (best effort, as in commit).
            for d in dirs {
                if let Ok(d) = File::open(d) {
                    let _ = d.sync_all();
                }
            }
            Ok(())
        });
        // What an error left is removed (those renamed are in place).
        discard(files);
        renamed
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        if self.owner {
            discard(STAGED.lock().unwrap_or_else(PoisonError::into_inner).take().unwrap_or_default());
        }
    }
}

/// Removes staged temporaries (their targets stay as they were).
fn discard(files: impl IntoIterator<Item = (Registered, PathBuf)>) {
    for (tmp, _) in files {
        let _ = std::fs::remove_file(&tmp.0);
    }
}

/// Removes the temporaries of every output being written (for a panic, just before the
/// process ends); returns how many there were.
pub fn remove_temporaries() -> usize {
    remove_listed(&mut TEMPORARIES.lock().unwrap_or_else(PoisonError::into_inner))
}

/// Removes the temporaries of every output being written and ends the process with `code`
/// (a handler of SIGINT or SIGTERM), holding the list: no other thread creates a temporary
/// after the removal ([`Registered::create`] waits for the list).
pub fn remove_temporaries_then_exit(code: i32) -> ! {
    let mut list = TEMPORARIES.lock().unwrap_or_else(PoisonError::into_inner);
    remove_listed(&mut list);
    std::process::exit(code)
}

/// Removes the temporaries `list` holds and empties it; returns how many there were.
fn remove_listed(list: &mut Vec<PathBuf>) -> usize {
    // Newest first (a piece's file before its folder). Another thread may still be writing: it
    // can add one more entry to a temporary folder before its next registration, which waits
    // for this lock; so a folder that is not gone yet is tried again.
    for p in list.iter().rev() {
        for _ in 0..100 {
            let removed = if p.is_dir() { std::fs::remove_dir_all(p) } else { std::fs::remove_file(p) };
            if removed.is_ok() || std::fs::symlink_metadata(p).is_err() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
    }
    let n = list.len();
    list.clear();
    n
}

/// [`remove_temporaries`] for a handler of SIGABRT, which runs inside the aborting thread
/// (a failed allocation aborts): it never waits for the list (a thread that holds it, perhaps
/// the aborting one, keeps it: nothing is removed) and tries each temporary once, without
/// retries, since nothing of the process runs after it. Returns how many it tried.
pub fn remove_temporaries_on_abort() -> usize {
    let Ok(list) = TEMPORARIES.try_lock() else { return 0 };
    for p in list.iter().rev() {
        let _ = if p.is_dir() { std::fs::remove_dir_all(p) } else { std::fs::remove_file(p) };
    }
    list.len()
}

/// Temporaries that an earlier, interrupted write of `path` left beside it
/// (`.NAME.*.tmp`, files or folders), excluding those this process is writing.
pub fn stale_temporaries(path: &Path) -> Vec<PathBuf> {
    let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else { return Vec::new() };
    let prefix = format!(".{name}.");
    let dir = parent_dir(path);
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let ours = TEMPORARIES.lock().unwrap_or_else(PoisonError::into_inner).clone();
    let mut found: Vec<PathBuf> = entries
        .filter_map(|e| e.ok())
        .filter(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.starts_with(&prefix) && n.ends_with(".tmp") && n.len() > prefix.len() + 4
        })
        .map(|e| dir.join(e.file_name()))
        .filter(|p| !ours.iter().any(|o| o.file_name() == p.file_name()))
        .collect();
    found.sort();
    found
}

/// A file written to a temporary name next to its target and renamed over the target on
/// [`commit`](AtomicFile::commit). Dropped without `commit`, the temporary file is removed
/// and the target is left as it was.
#[must_use = "an AtomicFile is only written to its target by commit()"]
pub struct AtomicFile {
    target: PathBuf,
    tmp: BufWriter<NamedTempFile>,
    _registered: Registered,
}

impl AtomicFile {
    /// Starts a new version of `path`. A symbolic link is followed: its target is replaced.
    pub fn create(path: &Path) -> Result<AtomicFile> {
        let target = if path.is_symlink() { canonical(path).unwrap_or(path.into()) } else { path.into() };
        let dir = parent_dir(&target);
        let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        #[cfg(unix)]
        {
            // Outputs get the permissions a plain create would give them (0666 less the umask),
            // or those of the file they replace, not the private mode of temporary files.
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&target).map(|m| m.permissions().mode() & 0o7777).unwrap_or(0o666);
            builder.permissions(std::fs::Permissions::from_mode(mode));
        }
        let (tmp, _registered) =
            Registered::create(|| builder.tempfile_in(dir), |t| t.path()).map_err(|e| Error::io(&target, e))?;
        Ok(AtomicFile { target, tmp: BufWriter::with_capacity(1 << 20, tmp), _registered })
    }

    /// The file this will become.
    pub fn path(&self) -> &Path {
        &self.target
    }

    /// Flushes, syncs the data to disk and renames the temporary file over the target (or,
    /// while an [`OutputSet`] is open, keeps it for the set's commit).
    pub fn commit(self) -> Result<()> {
        let io = |e: std::io::Error| Error::io(&self.target, e);
        let tmp = self.tmp.into_inner().map_err(|e| Error::io(&self.target, e.into_error()))?;
        tmp.as_file().sync_all().map_err(io)?;
        {
            let mut staged = STAGED.lock().unwrap_or_else(PoisonError::into_inner);
            if let Some(files) = staged.as_mut() {
                tmp.keep().map_err(|e| io(e.error))?;
                files.push((self._registered, self.target));
                return Ok(());
            }
        }
        tmp.persist(&self.target).map_err(|e| io(e.error))?;
        // The rename itself reaches the disk with the directory (best effort: not every
        // file system lets a directory be opened and synced).
        if let Ok(d) = File::open(parent_dir(&self.target)) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

impl AtomicFile {
    /// Appends the first `len` bytes of `src` (a copy inside the kernel where the system has
    /// one: spilled arrays of a large output are not read through user space).
    pub fn append_file(&mut self, src: &File, len: u64) -> std::io::Result<()> {
        use std::io::{Read, Seek};
        self.tmp.flush()?;
        let mut src = src;
        src.seek(std::io::SeekFrom::Start(0))?;
        let copied = std::io::copy(&mut src.take(len), self.tmp.get_mut().as_file_mut())?;
        if copied != len {
            return Err(std::io::Error::new(std::io::ErrorKind::UnexpectedEof, format!("{copied} of {len} bytes")));
        }
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.tmp.write(buf)
    }
    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.tmp.write_all(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.tmp.flush()
    }
}

/// Writes `path` atomically with `write`: complete, or not at all.
pub fn write_atomically<E: From<Error>>(
    path: &Path,
    write: impl FnOnce(&mut AtomicFile) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    let mut f = AtomicFile::create(path)?;
    write(&mut f)?;
    Ok(f.commit()?)
}

/// The directory a file is in (`.` for a bare file name).
pub(crate) fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// The lower-case extension of `path` ("" when it has none).
pub fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

/// Checks, before any work, that `path` can become an output: its extension is one of
/// `extensions`, it is not a directory or a device, and its directory exists and takes a new
/// file (tested by creating and removing one, which also catches read-only file systems).
pub fn check_output(path: &Path, extensions: &[&str]) -> Result<()> {
    if let Ok(m) = std::fs::metadata(path) {
        if m.is_dir() {
            return Err(Error::format(path, "is a directory, not a file to write"));
        }
        if !m.is_file() {
            return Err(Error::format(path, "is not a regular file (a device or a pipe); outputs are regular files"));
        }
    }
    let ext = extension(path);
    if !extensions.contains(&ext.as_str()) {
        let found = if ext.is_empty() { "no extension".to_string() } else { format!("'.{ext}'") };
        return Err(Error::format(
            path,
            format!("cannot write {found} here (known output formats: {})", extensions.join(", ")),
        ));
    }
    let dir = parent_dir(path);
    if !dir.exists() {
        return Err(Error::format(path, format!("the directory {} does not exist", dir.display())));
    }
    if !dir.is_dir() {
        return Err(Error::format(path, format!("{} is not a directory", dir.display())));
    }
    Registered::create(|| tempfile::Builder::new().prefix(".tetloc-write-check.").tempfile_in(dir), |t| t.path())
        .map_err(|e| Error::format(path, format!("cannot create files in {}: {e}", dir.display())))?;
    Ok(())
}

/// One file argument of a command, named as the user wrote it (e.g. `--out`).
#[derive(Clone, Copy, Debug)]
pub struct FileArg<'a> {
    pub name: &'a str,
    pub path: &'a Path,
}

impl<'a> FileArg<'a> {
    pub fn new(name: &'a str, path: &'a Path) -> Self {
        FileArg { name, path }
    }
}

/// Refuses a command whose output is one of its inputs, or two of whose outputs are the same
/// file: by canonical path, and by device and inode (hard links) where both files exist.
pub fn check_distinct(inputs: &[FileArg], outputs: &[FileArg]) -> Result<()> {
    let clash = |o: &FileArg, other: &FileArg, what: &str| {
        Error::Invalid(format!(
            "{} {} is the same file as the {what} {} {}; tetloc never writes over an {what}",
            o.name,
            o.path.display(),
            other.name,
            other.path.display()
        ))
    };
    // Each path's identity taken once and looked up: an orbit's 10,000 numbered frames were
    // compared pair by pair (5e7 comparisons, each a few system calls).
    let mut seen: std::collections::HashMap<FileKey, (&FileArg, &str)> = std::collections::HashMap::new();
    for i in inputs {
        if let Some(key) = file_key(i.path) {
            seen.entry(key).or_insert((i, "input"));
        }
    }
    for o in outputs {
        if let Some(key) = file_key(o.path) {
            if let Some(&(other, what)) = seen.get(&key) {
                return Err(clash(o, other, what));
            }
            seen.insert(key, (o, "output"));
        }
    }
    Ok(())
}

/// What names a file: its device and inode where it exists, else the canonical path that
/// creating it would give it.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
enum FileKey {
    Inode(u64, u64),
    Path(PathBuf),
}

fn file_key(p: &Path) -> Option<FileKey> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let Ok(m) = std::fs::metadata(p) {
            return Some(FileKey::Inode(m.dev(), m.ino()));
        }
    }
    canonical(p).map(FileKey::Path)
}

/// Whether two paths name the same file (or would, once `a` is created).
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (file_key(a), file_key(b)) {
        (Some(x), Some(y)) => x == y,
        _ => false,
    }
}

/// The canonical form of a path whose file may not exist yet (its directory must). A
/// dangling symbolic link stands for the file it points to, which writing it would create.
fn canonical(p: &Path) -> Option<PathBuf> {
    let mut p = p.to_path_buf();
    for _ in 0..8 {
        if let Ok(c) = std::fs::canonicalize(&p) {
            return Some(c);
        }
        match std::fs::read_link(&p) {
            Ok(target) => p = parent_dir(&p).join(target),
            Err(_) => return Some(std::fs::canonicalize(parent_dir(&p)).ok()?.join(p.file_name()?)),
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    /// A full-disk stand-in: accepts `left` bytes, then fails as a full disk does.
    struct FailAfter<W> {
        inner: W,
        left: usize,
    }
    impl<W: Write> Write for FailAfter<W> {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if self.left == 0 {
                return Err(std::io::Error::new(std::io::ErrorKind::StorageFull, "no space left on device"));
            }
            let n = self.inner.write(&buf[..buf.len().min(self.left)])?;
            self.left -= n;
            Ok(n)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            self.inner.flush()
        }
    }

    fn put(f: &mut AtomicFile, bytes: &[u8]) -> Result<()> {
        f.write_all(bytes).map_err(|e| Error::io("test", e))
    }

    #[test]
    fn commit_replaces_and_drop_keeps_the_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        std::fs::write(&path, "old").unwrap();
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(b"new, not committed").unwrap();
        drop(f);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        assert_eq!(entries(dir.path()), ["out.csv"], "the temporary file stays behind");
        write_atomically(&path, |f| put(f, b"new")).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert_eq!(entries(dir.path()), ["out.csv"]);
    }

    /// Leftovers of an interrupted write (`.NAME.*.tmp`, file or folder) are found; this
    /// process's own temporaries and other files are not.
    /// A temporary is listed in the same step that creates it: the signal handler, which
    /// waits for the list, cannot run between the two (it would leave the temporary behind).
    #[test]
    fn a_temporary_is_created_and_listed_in_one_step() {
        let dir = tempfile::tempdir().unwrap();
        let create = || {
            let held = std::thread::scope(|s| s.spawn(|| TEMPORARIES.try_lock().is_err()).join().unwrap());
            assert!(held, "the list is held while the temporary is created");
            tempfile::Builder::new().tempfile_in(dir.path())
        };
        let (made, registered) = Registered::create(create, |t| t.path()).unwrap();
        let listed = TEMPORARIES.lock().unwrap_or_else(PoisonError::into_inner).contains(&made.path().to_path_buf());
        assert!(listed, "listed as it is created");
        drop(registered);
    }

    #[test]
    fn stale_temporaries_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.npy");
        std::fs::write(dir.path().join(".r.npy.a1B2c3.tmp"), "half").unwrap();
        std::fs::create_dir(dir.path().join(".r.npy.x9.tmp")).unwrap();
        for other in [".r.npy.tmp", ".r.npyx.1.tmp", "r.npy.1.tmp", ".s.npy.1.tmp"] {
            std::fs::write(dir.path().join(other), "").unwrap();
        }
        let live = AtomicFile::create(&path).unwrap();
        let names: Vec<String> =
            stale_temporaries(&path).iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
        assert_eq!(names, [".r.npy.a1B2c3.tmp", ".r.npy.x9.tmp"]);
        drop(live);
    }

    #[test]
    fn a_write_failure_leaves_the_old_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ids.bin");
        std::fs::write(&path, "previous result").unwrap();
        let err = write_atomically(&path, |f| {
            let mut w = FailAfter { inner: f, left: 1000 };
            (0..100).try_for_each(|_| w.write_all(&[7u8; 100])).map_err(|e| Error::io("ids.bin", e))
        })
        .unwrap_err();
        assert!(err.to_string().contains("no space left"), "{err}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "previous result");
        assert_eq!(entries(dir.path()), ["ids.bin"]);
    }

    #[test]
    fn a_failed_rename_leaves_no_temporary() {
        // The target is a directory: the rename fails after everything was written.
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("taken.vtu")).unwrap();
        std::fs::write(dir.path().join("taken.vtu/keep"), "x").unwrap();
        let e = write_atomically(&dir.path().join("taken.vtu"), |f| put(f, b"data")).unwrap_err();
        assert!(e.to_string().contains("taken.vtu"), "{e}");
        assert_eq!(entries(dir.path()), ["taken.vtu"]);
        assert_eq!(std::fs::read_to_string(dir.path().join("taken.vtu/keep")).unwrap(), "x");
    }

    #[cfg(unix)]
    #[test]
    fn outputs_get_ordinary_permissions_and_links_are_followed() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.npy");
        write_atomically(&path, |f| put(f, b"1")).unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_ne!(mode & 0o044, 0, "mode {mode:o}: readable only by the owner, unlike a plain create");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).unwrap();
        let link = dir.path().join("link.npy");
        std::os::unix::fs::symlink(&path, &link).unwrap();
        write_atomically(&link, |f| put(f, b"2")).unwrap();
        assert!(link.is_symlink());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "2");
        assert_eq!(std::fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o640);
    }

    #[test]
    fn output_paths_are_checked_up_front() {
        let dir = tempfile::tempdir().unwrap();
        let ok = dir.path().join("x.npy");
        check_output(&ok, &["npy", "csv"]).unwrap();
        assert_eq!(entries(dir.path()), Vec::<String>::new(), "checking creates nothing");
        let e = check_output(&dir.path().join("o.h5"), &["npy", "csv"]).unwrap_err().to_string();
        assert!(e.contains("o.h5") && e.contains("'.h5'") && e.contains("npy, csv"), "{e}");
        let e = check_output(&dir.path().join("no/such/x.npy"), &["npy"]).unwrap_err().to_string();
        assert!(e.contains("does not exist"), "{e}");
        std::fs::create_dir(dir.path().join("d.npy")).unwrap();
        let e = check_output(&dir.path().join("d.npy"), &["npy"]).unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
        // A device as an output: renaming over it would replace the device node.
        #[cfg(unix)]
        {
            let e = check_output(Path::new("/dev/null"), &["npy"]).unwrap_err().to_string();
            assert!(e.contains("not a regular file"), "{e}");
        }
        std::fs::write(dir.path().join("plain"), "").unwrap();
        let e = check_output(&dir.path().join("plain/x.npy"), &["npy"]).unwrap_err().to_string();
        assert!(e.contains("is not a directory"), "{e}");
        // A directory that takes no new file, even for root.
        #[cfg(target_os = "linux")]
        {
            let e = check_output(Path::new("/proc/x.npy"), &["npy"]).unwrap_err().to_string();
            assert!(e.contains("cannot create files in /proc"), "{e}");
        }
    }

    #[test]
    fn an_output_that_is_an_input_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = dir.path().join("mesh.vtu");
        std::fs::write(&mesh, "mesh").unwrap();
        let points = dir.path().join("p.npy");
        std::fs::write(&points, "points").unwrap();
        let inputs = [FileArg::new("MESH", &mesh), FileArg::new("--points", &points)];
        let other = dir.path().join("ids.npy");
        check_distinct(&inputs, &[FileArg::new("--out", &other)]).unwrap();
        // The same name, another spelling of it, a hard link and a symbolic link.
        let dotted = dir.path().join(".").join("mesh.vtu");
        let hard = dir.path().join("hard.vtu");
        std::fs::hard_link(&mesh, &hard).unwrap();
        let mut outs = vec![mesh.clone(), dotted, hard];
        #[cfg(unix)]
        {
            let soft = dir.path().join("soft.vtu");
            std::os::unix::fs::symlink(&mesh, &soft).unwrap();
            outs.push(soft);
        }
        for o in &outs {
            let e = check_distinct(&inputs, &[FileArg::new("--out", o)]).unwrap_err().to_string();
            assert!(e.contains("--out") && e.contains("input MESH") && e.contains("mesh.vtu"), "{e}");
        }
        let e = check_distinct(&inputs, &[FileArg::new("--values", &points)]).unwrap_err().to_string();
        assert!(e.contains("--values") && e.contains("--points"), "{e}");
        // Two outputs into one file, which does not exist yet.
        let e = check_distinct(&inputs, &[FileArg::new("--out", &other), FileArg::new("--values", &other)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("--values") && e.contains("output --out"), "{e}");
        assert_eq!(std::fs::read_to_string(&mesh).unwrap(), "mesh");
        // An orbit's 10,000 numbered frames, the last another spelling of the 7th.
        let mut frames: Vec<PathBuf> = (0..10_000).map(|k| dir.path().join(format!("f_{k:05}.png"))).collect();
        let outs = |frames: &[PathBuf]| -> Result<()> {
            check_distinct(&inputs, &frames.iter().map(|f| FileArg::new("--out", f)).collect::<Vec<_>>())
        };
        outs(&frames).unwrap();
        *frames.last_mut().unwrap() = dir.path().join(".").join("f_00007.png");
        let e = outs(&frames).unwrap_err().to_string();
        let seventh = format!("the output --out {}; ", frames[7].display());
        assert!(e.contains("./f_00007.png is the same file as") && e.contains(&seventh), "{e}");
    }
}

/// The property of issue 29: for any output path relative to the inputs (a partitioned
/// mesh's listing and pieces; the same folder, the pieces' folder, through symbolic links to
/// the folder or a piece, a hard link, `.` and `..`), an output that is an input is refused,
/// and a write that fails or completes changes no input; a failed write also leaves the
/// previous output whole and no temporary behind.
#[cfg(all(test, unix))]
mod path_props {
    use super::*;
    use proptest::prelude::*;
    use std::os::unix::fs::MetadataExt;
    use std::sync::OnceLock;

    /// `root/m.pvtu` with its pieces `root/m/m_*.vtu`; `link_dir` → `m`, `link_piece.vtu` →
    /// `m/m_0.vtu`, `hard.vtu` a hard link of `m/m_1.vtu`, and `other/old.vtu`, an earlier
    /// output. Made once for every case.
    fn fixture() -> &'static (PathBuf, Vec<PathBuf>) {
        static FIXTURE: OnceLock<(PathBuf, Vec<PathBuf>)> = OnceLock::new();
        FIXTURE.get_or_init(|| {
            let root = std::env::temp_dir().join(format!("tetloc-output-props-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&root);
            std::fs::create_dir_all(root.join("other")).unwrap();
            let mesh = crate::test_support::KuhnGrid::new(2).mesh("m");
            let listing = root.join("m.pvtu");
            crate::partition::write_pvtu(&mesh, 2, &listing, false, |_| {}).unwrap();
            std::os::unix::fs::symlink(root.join("m"), root.join("link_dir")).unwrap();
            std::os::unix::fs::symlink(root.join("m/m_0.vtu"), root.join("link_piece.vtu")).unwrap();
            std::fs::hard_link(root.join("m/m_1.vtu"), root.join("hard.vtu")).unwrap();
            std::fs::write(root.join("other/old.vtu"), "an earlier output").unwrap();
            let inputs = crate::input_files(&listing, None);
            assert!(inputs.len() >= 3, "the listing and its pieces: {inputs:?}");
            (root, inputs)
        })
    }

    fn bytes(paths: &[PathBuf]) -> Vec<Vec<u8>> {
        paths.iter().map(|p| std::fs::read(p).unwrap()).collect()
    }

    /// Folders on the way to the output (all inside the fixture) and the output's name.
    fn output_path() -> impl Strategy<Value = PathBuf> {
        let step = prop_oneof![Just("m"), Just("link_dir"), Just("other"), Just("."), Just("m/.."), Just("other/../m")];
        let name = prop_oneof![
            Just("m_0.vtu"),
            Just("m_1.vtu"),
            Just("m.pvtu"),
            Just("link_piece.vtu"),
            Just("hard.vtu"),
            Just("old.vtu"),
            Just("new.vtu"),
        ];
        (prop::collection::vec(step, 0..4), name).prop_map(|(steps, name)| {
            let mut p = fixture().0.clone();
            steps.iter().for_each(|s| p.push(s));
            p.join(name)
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        #[test]
        fn no_output_path_overwrites_an_input(out in output_path(), fail_after in 0usize..64) {
            let (root, inputs) = fixture();
            let before = bytes(inputs);
            let previous = std::fs::read(&out).ok();
            // The truth, apart from the code under test: the file the path reaches (links
            // followed) is an input's, by device and inode.
            let inode = |p: &Path| std::fs::metadata(p).ok().map(|m| (m.dev(), m.ino()));
            let is_input = inode(&out).is_some_and(|o| inputs.iter().any(|i| inode(i) == Some(o)));
            let args: Vec<FileArg> = inputs.iter().map(|i| FileArg::new("MESH", i)).collect();
            let refused = check_distinct(&args, &[FileArg::new("--out", &out)]).is_err();
            prop_assert_eq!(refused, is_input, "{}", out.display());
            if refused {
                return Ok(());
            }
            // A path through a folder that is not there: the write cannot start.
            let Ok(mut f) = AtomicFile::create(&out) else {
                prop_assert!(!parent_dir(&out).is_dir(), "{}", out.display());
                prop_assert_eq!(bytes(inputs), before);
                return Ok(());
            };
            // A write that fails part way (dropped before its commit): nothing changed, no
            // temporary left.
            f.write_all(&vec![7u8; fail_after]).unwrap();
            drop(f);
            prop_assert_eq!(std::fs::read(&out).ok(), previous.clone());
            let dir = parent_dir(&out);
            let temporaries: Vec<_> = std::fs::read_dir(dir)
                .unwrap()
                .filter_map(|e| e.ok())
                .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
                .collect();
            prop_assert!(temporaries.is_empty(), "{:?}", temporaries);
            // A write that completes: the output changes, no input does.
            let mut f = AtomicFile::create(&out).unwrap();
            f.write_all(b"a new output").unwrap();
            f.commit().unwrap();
            prop_assert_eq!(std::fs::read(&out).unwrap(), b"a new output".to_vec());
            prop_assert_eq!(bytes(inputs), before);
            // Back to the fixture for the next case.
            match previous {
                Some(p) => std::fs::write(&out, p).unwrap(),
                None => std::fs::remove_file(&out).unwrap(),
            }
            prop_assert!(root.join("m.pvtu").is_file());
        }
    }
}
