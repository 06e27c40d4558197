//! The CPU locator: BVH traversal and the shared point-in-tet test, parallel over points
//! with rayon.

use super::{check_lengths, BatchLocator, OUTSIDE};
use crate::bvh::{BuildPreset, Bvh};
use crate::error::Result;
use crate::geom::{self, Bary, Vec3};
use crate::mesh::{FieldLocation, Mesh};
use rayon::prelude::*;
use std::sync::Arc;

/// Points handed to one rayon task: large enough to amortise scheduling, small enough to balance.
const CHUNK: usize = 4096;

pub struct CpuLocator {
    mesh: Arc<Mesh>,
    bvh: Bvh,
}

impl CpuLocator {
    pub fn new(mesh: Arc<Mesh>) -> CpuLocator {
        Self::with_preset(mesh, BuildPreset::Fast)
    }

    pub fn with_preset(mesh: Arc<Mesh>, preset: BuildPreset) -> CpuLocator {
        let bvh = Bvh::build(&mesh.points, &mesh.tets, preset);
        CpuLocator { mesh, bvh }
    }

    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    pub fn mesh(&self) -> &Arc<Mesh> {
        &self.mesh
    }

    /// The tet containing `p` and the barycentric coordinates of `p` in it.
    #[inline]
    pub fn locate_point(&self, p: Vec3) -> Option<(u32, Bary)> {
        let nodes = &self.bvh.nodes;
        if nodes.is_empty() || !nodes[0].contains(p) {
            return None;
        }
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut i = 0u32;
        loop {
            let n = &nodes[i as usize];
            if n.is_leaf() {
                for &t in &self.bvh.prim_ids[n.first as usize..(n.first + n.count) as usize] {
                    if let Some(b) = geom::point_in_tet(self.mesh.tets[t as usize], &self.mesh.points, p) {
                        return Some((t, b));
                    }
                }
            } else {
                let (l, r) = (i + 1, n.first);
                let (in_l, in_r) = (nodes[l as usize].contains(p), nodes[r as usize].contains(p));
                if in_l {
                    if in_r {
                        stack[sp] = r;
                        sp += 1;
                    }
                    i = l;
                    continue;
                } else if in_r {
                    i = r;
                    continue;
                }
            }
            if sp == 0 {
                return None;
            }
            sp -= 1;
            i = stack[sp];
        }
    }

    /// The value of `field` at `p`: interpolated (per vertex) or looked up (per cell); NaN outside.
    #[inline]
    fn sample_point(&self, p: Vec3, values: &[f32], location: FieldLocation) -> f32 {
        match self.locate_point(p) {
            None => f32::NAN,
            Some((t, bary)) => match location {
                FieldLocation::Vertex => geom::interpolate(self.mesh.tets[t as usize], bary, values),
                FieldLocation::Cell => values[t as usize],
            },
        }
    }
}

impl BatchLocator for CpuLocator {
    fn name(&self) -> &str {
        "cpu"
    }

    fn locate(&mut self, points: &[Vec3], ids: &mut [i32]) -> Result<()> {
        check_lengths(points.len(), ids.len())?;
        ids.par_chunks_mut(CHUNK).zip(points.par_chunks(CHUNK)).for_each(|(out, pts)| {
            for (o, &p) in out.iter_mut().zip(pts) {
                *o = self.locate_point(p).map_or(OUTSIDE, |(t, _)| t as i32);
            }
        });
        Ok(())
    }

    fn sample(&mut self, points: &[Vec3], field: &str, values: &mut [f32]) -> Result<()> {
        check_lengths(points.len(), values.len())?;
        let f = self.mesh.field(field)?;
        values.par_chunks_mut(CHUNK).zip(points.par_chunks(CHUNK)).for_each(|(out, pts)| {
            for (o, &p) in out.iter_mut().zip(pts) {
                *o = self.sample_point(p, &f.values, f.location);
            }
        });
        Ok(())
    }
}
