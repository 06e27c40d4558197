//! `output::OutputSet`: files that appear together or not at all. Its own test binary, since
//! an open set gathers every file committed in the process, other tests' files included.

use std::path::Path;
use tetloc_core::error::Error;
use tetloc_io::output::{write_atomically, OutputSet};

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

fn write(path: &Path, text: &str) -> tetloc_core::error::Result<()> {
    write_atomically(path, |f| std::io::Write::write_all(f, text.as_bytes()).map_err(|e| Error::io(path, e)))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_default()
}

#[test]
fn a_set_appears_whole_or_not_at_all() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b, index) = (dir.path().join("a_0.txt"), dir.path().join("a_1.txt"), dir.path().join("a.idx"));
    for (p, t) in [(&a, "old 0"), (&b, "old 1"), (&index, "old index")] {
        std::fs::write(p, t).unwrap();
    }

    // Committed files wait under their temporary names until the set commits.
    let set = OutputSet::begin();
    write(&a, "new 0").unwrap();
    assert_eq!(read(&a), "old 0", "a file of an open set is not in place yet");
    assert_eq!(entries(dir.path()).len(), 4, "its temporary is kept: {:?}", entries(dir.path()));
    write(&b, "new 1").unwrap();
    set.commit_after(|| std::fs::remove_file(&index).map_err(|e| Error::io(&index, e))).unwrap();
    assert_eq!((read(&a), read(&b)), ("new 0".into(), "new 1".into()));
    assert_eq!(entries(dir.path()), ["a_0.txt", "a_1.txt"], "the index went first, no temporary is left");

    // A set dropped (a later step failed) leaves every target as it was, and no temporary.
    std::fs::write(&index, "index").unwrap();
    let set = OutputSet::begin();
    write(&a, "newer 0").unwrap();
    drop(set);
    assert_eq!((read(&a), read(&b)), ("new 0".into(), "new 1".into()));
    assert_eq!(entries(dir.path()), ["a.idx", "a_0.txt", "a_1.txt"]);

    // So does one whose first action fails: nothing is renamed.
    let set = OutputSet::begin();
    write(&a, "newer 0").unwrap();
    let e = set.commit_after(|| Err(Error::format(&index, "cannot remove"))).unwrap_err();
    assert!(e.to_string().contains("cannot remove"), "{e}");
    assert_eq!(read(&a), "new 0");
    assert_eq!(entries(dir.path()), ["a.idx", "a_0.txt", "a_1.txt"]);

    // A set opened inside another adds to it: the outer one commits.
    let outer = OutputSet::begin();
    let inner = OutputSet::begin();
    write(&b, "inner 1").unwrap();
    inner.commit().unwrap();
    assert_eq!(read(&b), "new 1", "the inner set's commit waits for the outer one");
    outer.commit().unwrap();
    assert_eq!(read(&b), "inner 1");

    // Outside a set, a commit is in place at once.
    write(&a, "alone").unwrap();
    assert_eq!(read(&a), "alone");
    assert_eq!(entries(dir.path()), ["a.idx", "a_0.txt", "a_1.txt"]);
}
