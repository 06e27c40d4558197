//! The listing of a parallel VTK unstructured grid (`.pvtu`): the VTU files of its pieces,
//! in order. ParaView writes one per solver rank; `tetloc partition` writes them too. The
//! pieces themselves are read by [`super::pieces`].

use super::xml;
use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};

/// The piece files a `.pvtu` lists (`<Piece Source="...">`), relative paths resolved
/// against the folder of the `.pvtu`; `path` names the file in errors and anchors them.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Vec<PathBuf>> {
    let fail = |msg: String| Error::format(path, msg);
    let doc = xml::parse(bytes, "AppendedData").map_err(fail)?;
    let grid = super::pieces::listing_element(&doc, path, "PUnstructuredGrid", "a .pvtu")?;
    let files = grid
        .children_named("Piece")
        .enumerate()
        .map(|(k, p)| match p.attr("Source") {
            Some(s) if !s.trim().is_empty() => Ok(super::pieces::resolve(path, s.trim())),
            _ => Err(fail(format!("<Piece> {k} has no Source file"))),
        })
        .collect::<Result<Vec<_>>>()?;
    if files.is_empty() {
        return Err(fail("<PUnstructuredGrid> lists no <Piece>".into()));
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_pieces_relative_to_the_file() {
        let src = r#"<?xml version="1.0"?>
<VTKFile type="PUnstructuredGrid" version="1.0" byte_order="LittleEndian">
  <PUnstructuredGrid GhostLevel="0">
    <PPoints><PDataArray type="Float32" NumberOfComponents="3"/></PPoints>
    <Piece Source="m/m_0.vtu"/>
    <Piece Source="/abs/m_1.vtu"/>
  </PUnstructuredGrid>
</VTKFile>"#;
        let files = parse(src.as_bytes(), Path::new("dir/m.pvtu")).unwrap();
        assert_eq!(files, [PathBuf::from("dir/m/m_0.vtu"), PathBuf::from("/abs/m_1.vtu")]);
        let e = |s: &str| parse(s.as_bytes(), Path::new("x.pvtu")).unwrap_err().to_string();
        assert!(e(&src.replace("PUnstructuredGrid\" version", "UnstructuredGrid\" version")).contains("x.pvtu: a VTK"));
        assert!(e(&src.replace("Source=\"m/m_0.vtu\"", "")).contains("<Piece> 0 has no Source"));
        assert!(e(&src.replace("</PUnstructuredGrid>", "")).starts_with("x.pvtu: malformed XML"));
        assert!(e("<VTKFile type=\"PUnstructuredGrid\"><PUnstructuredGrid/></VTKFile>").contains("no <Piece>"));
    }
}
