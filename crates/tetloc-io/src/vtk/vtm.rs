//! The listing of a VTK multiblock data set (`.vtm`): the files of its blocks, depth first in
//! document order. tetloc reads the blocks that are unstructured grids (`.vtu`, or a `.pvtu`
//! whose pieces are) as the pieces of one mesh ([`super::pieces`]).

use super::xml::{self, Node};
use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};

/// The block files a `.vtm` lists (`<DataSet file="...">` at any depth of `<Block>`s),
/// relative paths resolved against the folder of the `.vtm`. Empty blocks (no `file`) are
/// skipped.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Vec<PathBuf>> {
    let fail = |msg: String| Error::format(path, msg);
    let doc = xml::parse(bytes, "AppendedData").map_err(fail)?;
    let set = super::pieces::listing_element(&doc, path, "vtkMultiBlockDataSet", "a .vtm")?;
    let mut files = Vec::new();
    collect(set, path, &mut files);
    if files.is_empty() {
        return Err(fail("the multiblock data set lists no file".into()));
    }
    Ok(files)
}

fn collect(node: &Node, path: &Path, out: &mut Vec<PathBuf>) {
    for c in &node.children {
        match c.name.as_str() {
            "DataSet" | "Piece" => match c.attr("file") {
                Some(f) if !f.trim().is_empty() => out.push(super::pieces::resolve(path, f.trim())),
                _ => collect(c, path, out),
            },
            "Block" => collect(c, path, out),
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_blocks_depth_first() {
        let src = r#"<?xml version="1.0"?>
<VTKFile type="vtkMultiBlockDataSet" version="1.0">
  <vtkMultiBlockDataSet>
    <Block index="0" name="a">
      <DataSet index="0" file="m/m_0_0.vtu"/>
      <DataSet index="1"/>
      <Block index="1"><DataSet index="0" file="m/m_0_1.vtu"/></Block>
    </Block>
    <DataSet index="1" name="b" file="m/m_1.vtu"/>
  </vtkMultiBlockDataSet>
</VTKFile>"#;
        let files = parse(src.as_bytes(), Path::new("d/m.vtm")).unwrap();
        let want = ["d/m/m_0_0.vtu", "d/m/m_0_1.vtu", "d/m/m_1.vtu"].map(PathBuf::from);
        assert_eq!(files, want);
        let e = |s: &str| parse(s.as_bytes(), Path::new("x.vtm")).unwrap_err().to_string();
        assert!(e(&src.replace("vtkMultiBlockDataSet\" version", "PolyData\" version")).contains("x.vtm: a VTK"));
        assert!(e(&src.replace("</Block>\n    <DataSet", "\n    <DataSet")).starts_with("x.vtm: "));
        let empty =
            "<VTKFile type=\"vtkMultiBlockDataSet\"><vtkMultiBlockDataSet><Block/></vtkMultiBlockDataSet></VTKFile>";
        assert!(e(empty).contains("lists no file"));
    }
}
