//! Gmsh's element types: how many nodes each has, and whether it is a volume cell tetloc reads
//! (of which order), another volume element, or a lower-dimensional one that the reader ignores.

use crate::cursor::Cursor;
use tetloc_core::cell::CellType;
use tetloc_core::error::Error;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kind {
    /// 0-D, 1-D and 2-D elements: ignored.
    Lower,
    /// A volume cell tetloc reads (a tetrahedron of any order, or a type `CellType::from_gmsh`
    /// knows), with its Gmsh type code and polynomial order.
    Cell { code: u8, order: u8 },
    /// Any other volume element, by family name: the file is refused, counting them.
    Volume(&'static str),
}

/// Node count and kind of a Gmsh element type (numbers from gmsh's `GmshDefines.h`).
/// `None` for types without a fixed node count (polygons, polyhedra) or that tetloc does not
/// know.
pub(super) fn element_type(t: i64) -> Option<(usize, Kind)> {
    use Kind::*;
    let lower = |n: usize| (n, Lower);
    let tet = |n: usize, order: i64| (n, Cell { code: t as u8, order: order as u8 });
    let vol = |n: usize, name| match u8::try_from(t).ok().and_then(CellType::from_gmsh) {
        Some((ty, _)) => (n, Cell { code: t as u8, order: ty.def().order() }),
        None => (n, Volume(name)),
    };
    Some(match t {
        15 => lower(1),
        1 => lower(2),
        8 => lower(3),
        26..=28 => lower(t as usize - 22),
        62..=66 => lower(t as usize - 55),
        2 => lower(3),
        3 => lower(4),
        9 => lower(6),
        10 => lower(9),
        16 => lower(8),
        20 => lower(9),
        21 => lower(10),
        22 => lower(12),
        23 | 24 => lower(15),
        25 => lower(21),
        36 => lower(16),
        37 => lower(25),
        38 => lower(36),
        39 => lower(12),
        40 => lower(16),
        41 => lower(20),
        42 => lower(28),
        43 => lower(36),
        44 => lower(45),
        45 => lower(55),
        46 => lower(66),
        47 => lower(49),
        48 => lower(64),
        49 => lower(81),
        50 => lower(100),
        51 => lower(121),
        52 => lower(18),
        53 => lower(21),
        54 => lower(24),
        55 => lower(27),
        56 => lower(30),
        57 => lower(24),
        58 => lower(28),
        59 => lower(32),
        60 => lower(36),
        61 => lower(40),
        4 => tet(4, 1),
        11 => tet(10, 2),
        29 => tet(20, 3),
        30 => tet(35, 4),
        31 => tet(56, 5),
        32 => tet(22, 4),
        33 => tet(28, 5),
        137 => tet(16, 3),
        // Complete tetrahedra of order 6..10.
        71..=75 => {
            let k = t - 65;
            tet(((k + 1) * (k + 2) * (k + 3) / 6) as usize, k)
        }
        // Incomplete (no interior nodes) tetrahedra of order 6..10.
        79..=83 => {
            let k = t - 73;
            tet((4 + 6 * (k - 1)) as usize, k)
        }
        5 => vol(8, "hexahedron"),
        12 => vol(27, "hexahedron"),
        17 => vol(20, "hexahedron"),
        92 => vol(64, "hexahedron"),
        93 => vol(125, "hexahedron"),
        94..=98 => vol(((t - 88) as usize).pow(3), "hexahedron"),
        99..=105 => vol((8 + 12 * (t - 97)) as usize, "hexahedron"),
        6 => vol(6, "prism"),
        13 => vol(18, "prism"),
        18 => vol(15, "prism"),
        90 => vol(40, "prism"),
        91 => vol(75, "prism"),
        106..=110 => {
            let k = t - 101;
            vol(((k + 1) * (k + 1) * (k + 2) / 2) as usize, "prism")
        }
        111..=117 => vol((6 + 9 * (t - 109)) as usize, "prism"),
        7 => vol(5, "pyramid"),
        14 => vol(14, "pyramid"),
        19 => vol(13, "pyramid"),
        118..=124 => {
            let k = t - 115;
            vol(((k + 1) * (k + 2) * (2 * k + 3) / 6) as usize, "pyramid")
        }
        125..=131 => vol((5 + 8 * (t - 123)) as usize, "pyramid"),
        140 => vol(4, "trihedron"),
        _ => return None,
    })
}

/// The VTK cell type of a point, line or surface element of Gmsh type `code` whose nodes VTK
/// orders as Gmsh does (corners, then edge midpoints, then the face centre), if there is one.
pub(super) fn vtk_lower(code: u8) -> Option<u8> {
    Some(match code {
        15 => 1,  // point: VTK_VERTEX
        1 => 3,   // 2-node line: VTK_LINE
        8 => 21,  // 3-node line: VTK_QUADRATIC_EDGE
        2 => 5,   // triangle: VTK_TRIANGLE
        9 => 22,  // 6-node triangle: VTK_QUADRATIC_TRIANGLE
        3 => 9,   // quadrangle: VTK_QUAD
        16 => 23, // 8-node quadrangle: VTK_QUADRATIC_QUAD
        10 => 28, // 9-node quadrangle: VTK_BIQUADRATIC_QUAD
        _ => return None,
    })
}

/// An error unless the ASCII element line at the cursor holds `words` more words: a type
/// that is not the element's (`99`, a 32-node hexahedron, written over a tet) would
/// otherwise read the next lines' numbers as its nodes. `tag` and `ty` name the element.
pub(super) fn check_line(c: &mut Cursor, pos: usize, tag: u64, ty: i64, words: usize) -> Result<(), Error> {
    c.skip_ws_on_line();
    let found = c.words_on_line();
    if found == words {
        return Ok(());
    }
    let what = match element_type(ty) {
        Some((nn, Kind::Lower)) => format!("a point, line or surface element of {nn} nodes"),
        Some((nn, Kind::Cell { .. })) => format!("a volume cell of {nn} nodes"),
        Some((nn, Kind::Volume(name))) => format!("a {name} of {nn} nodes"),
        None => return Err(unknown_type(c, pos, ty)),
    };
    Err(c.fail_at(
        pos,
        format!(
            "element {tag}: element type {ty} is {what}, but its line holds {found} more numbers where {words} \
             were expected (is the element type right?)"
        ),
    ))
}

/// The error for a type that [`element_type`] does not know, at byte `pos`.
pub(super) fn unknown_type(c: &Cursor, pos: usize, ty: i64) -> Error {
    c.fail_at(
        pos,
        format!("element type {ty} is not a Gmsh element type with a fixed number of nodes that tetloc knows"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Node counts follow the closed forms of complete and serendipity (incomplete) elements.
    #[test]
    fn node_counts_follow_the_element_families() {
        let tet = |k: usize| (k + 1) * (k + 2) * (k + 3) / 6;
        let complete_tets = [(4, 1), (11, 2), (29, 3), (30, 4), (31, 5), (71, 6), (72, 7), (73, 8), (74, 9), (75, 10)];
        for (ty, order) in complete_tets {
            assert_eq!(element_type(ty), Some((tet(order), Kind::Cell { code: ty as u8, order: order as u8 })));
        }
        // Incomplete tets: corners and edge nodes only.
        for (ty, order) in [(137, 3), (32, 4), (33, 5), (79, 6), (83, 10)] {
            let kind = Kind::Cell { code: ty as u8, order: order as u8 };
            assert_eq!(element_type(ty), Some((4 + 6 * (order - 1), kind)), "type {ty}");
        }
        let hex = |k: usize| (k + 1).pow(3);
        // Hexahedra tetloc reads are cells; those of order 3 and up are refused.
        for (ty, order) in [(5, 1), (12, 2)] {
            assert_eq!(element_type(ty), Some((hex(order), Kind::Cell { code: ty as u8, order: order as u8 })));
        }
        for (ty, order) in [(92, 3), (93, 4), (94, 5), (98, 9)] {
            assert_eq!(element_type(ty), Some((hex(order), Kind::Volume("hexahedron"))), "type {ty}");
        }
        let cell = |code: u8, order: u8| Kind::Cell { code, order };
        assert_eq!(element_type(17), Some((20, cell(17, 2))));
        assert_eq!(element_type(6), Some((6, cell(6, 1))));
        assert_eq!(element_type(18), Some((15, cell(18, 2))));
        assert_eq!(element_type(13), Some((18, cell(13, 2))));
        assert_eq!(element_type(7), Some((5, cell(7, 1))));
        assert_eq!(element_type(19), Some((13, cell(19, 2))));
        assert_eq!(element_type(14), Some((14, cell(14, 2))));
        assert_eq!(element_type(140), Some((4, Kind::Volume("trihedron"))));
        assert_eq!(element_type(2), Some((3, Kind::Lower)));
        assert_eq!(element_type(15), Some((1, Kind::Lower)));
        for unknown in [0, 67, 200, -1] {
            assert_eq!(element_type(unknown), None);
        }
    }
}
