//! Locating points from a tet near each on the GPU (`shaders/hinted.comp`): soft-bvh's
//! pathlines ask where each particle is now, starting from the tet it was in, so the kernel
//! walks through face neighbours from that tet and searches (entry grid, BVH) only where the
//! walk fails or ends on a face; the answers are `locate`'s, tie rule included. Only for meshes
//! whose f32 working copy is the file's data (elsewhere `locate` certifies its answers on the
//! file's coordinates, and this falls back to it).

use crate::error::VkResult;
use crate::interface::*;
use crate::locator::VulkanLocator;
use crate::memory::{Buffer, BufferDesc, MemKind};
use crate::pipeline::{Binding, Descriptors, Pipeline};
use rayon::prelude::*;
use tetloc_core::geom::Vec3;
use tetloc_core::locate::{BatchLocator, HintedLocator};

/// Most points one launch locates.
const BATCH: usize = 1 << 22;
const WORKGROUP: u32 = 128;

/// The hinted locate's pipeline over a locator's mesh and structure, with buffers for
/// `capacity` points a launch.
pub(crate) struct Hinted {
    // Field order is drop order: the pipeline before the buffers it names.
    pipeline: Pipeline,
    desc: Descriptors,
    push: Params,
    /// Each point's coordinates (working frame) and hint, as `[u32; 4]`.
    points: Buffer,
    ids: Buffer,
    capacity: usize,
    _neighbors: Option<Buffer>,
}

impl Hinted {
    /// `None` where the kernel has no hinted shader.
    fn open(loc: &mut VulkanLocator, capacity: usize) -> VkResult<Option<Hinted>> {
        let mut res = loc.resources_for(OUT_IDS, false);
        let Some(program) = res.plan.hinted else { return Ok(None) };
        let neighbors = res.bind_own_neighbors("hinted tet neighbours")?;
        let dev = res.dev;
        let points =
            dev.create_buffer(BufferDesc::io(MemKind::Query, (capacity * 16) as u64), "hinted points", None)?;
        let ids = dev.create_buffer(BufferDesc::io(MemKind::Query, (capacity * 4) as u64), "hinted ids", None)?;
        let mut bindings = res.bindings;
        bindings.extend([Binding::buffer(B_HINTED, &points), Binding::buffer(B_HINTED_IDS, &ids)]);
        let ctx = dev.ctx().clone();
        let desc = Descriptors::new(&ctx, &bindings, program.stages())?;
        let spec = res.spec.set(sc::WORKGROUP, WORKGROUP);
        let pipeline = program.pipeline(dev, desc.layout, res.f64, &spec)?;
        Ok(Some(Hinted { pipeline, desc, push: res.params, points, ids, capacity, _neighbors: neighbors }))
    }
}

impl VulkanLocator {
    /// Whether [`HintedLocator::locate_from`] runs the hinted kernel here: a kernel that has
    /// one, on tets whose f32 copy is the file's data.
    pub(crate) fn walks_from_hints(&self) -> bool {
        self.plan().hinted.is_some() && !self.mesh().wants_f64_points() && self.mesh().cells.is_none()
    }
}

impl HintedLocator for VulkanLocator {
    fn locate_from(&mut self, points: &[Vec3], hints: &[i32], ids: &mut [i32]) -> tetloc_core::Result<()> {
        if !self.walks_from_hints() || hints.len() != points.len() || ids.len() != points.len() {
            return self.locate(points, ids);
        }
        let want = points.len().clamp(1, BATCH);
        if self.hinted.as_ref().is_none_or(|h| h.capacity < want) {
            self.hinted = None; // its buffers freed before the larger ones are made
            self.hinted = Hinted::open(self, want)?;
        }
        let Some(h) = self.hinted.take() else { return self.locate(points, ids) };
        let result = (|| -> VkResult<()> {
            let dev = self.device();
            for ((points, hints), ids) in points.chunks(BATCH).zip(hints.chunks(BATCH)).zip(ids.chunks_mut(BATCH)) {
                let n = points.len();
                let input: Vec<[u32; 4]> = (points.par_iter().zip(hints))
                    .map(|(p, &t)| [p[0].to_bits(), p[1].to_bits(), p[2].to_bits(), t.max(-1) as u32])
                    .collect();
                dev.write(&h.points, 0, bytemuck::cast_slice(&input))?;
                let push = Params { counts: [n as u32, 0, h.push.counts[2], 0], ..h.push };
                dev.run(|r| h.pipeline.record_points(r, &h.desc, &push, n, WORKGROUP))?;
                dev.download(&h.ids, 0, bytemuck::cast_slice_mut(ids))?;
            }
            Ok(())
        })();
        self.hinted = Some(h);
        Ok(result?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::context::test_context;
    use crate::{Kernel, LocatorOptions};
    use std::sync::Arc;
    use tetloc_core::gen::{self, Shape};
    use tetloc_core::locate::{locate_from, FiniteOnly};
    use tetloc_core::mesh::Mesh;

    /// From any hint (the right tet, a tet next to it, a far one, none, out of range) the
    /// answers are `locate`'s, for points inside, outside, on shared faces and at vertices,
    /// with packed ids and the own neighbour table (`small`) too; NaN points are outside (through `FiniteOnly`).
    #[test]
    fn hinted_answers_are_the_fresh_searchs() {
        let Some(ctx) = test_context("hinted_answers_are_the_fresh_searchs") else { return };
        let m = Arc::new(Mesh::new(gen::generate(Shape::Fusion, 20_000, 3), "fusion").unwrap());
        let n = m.n_tets();
        let mut points: Vec<Vec3> = (0..n).step_by(7).map(|t| m.tet_center(t)).collect();
        // On faces (a face's centroid) and at vertices: shared by several tets.
        for t in (0..n).step_by(97) {
            let v = m.tets[t].map(|i| m.points[i as usize]);
            points.push(std::array::from_fn(|k| (v[0][k] + v[1][k] + v[2][k]) / 3.0));
            points.push(v[3]);
        }
        let (lo, hi) = (m.info.bounds_min, m.info.bounds_max);
        let mut s = 7u64;
        for _ in 0..5000 {
            points.push(std::array::from_fn(|k| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                lo[k] + (hi[k] - lo[k]) * ((s >> 40) as f32 / (1u64 << 24) as f32)
            }));
        }
        for preset in ["fast", "small"] {
            let opts = LocatorOptions::preset(preset).expect("a preset");
            let mut gpu = FiniteOnly::new(VulkanLocator::new(ctx.clone(), m.clone(), Kernel::SoftBvh, opts).unwrap());
            let mut want = vec![0; points.len()];
            gpu.locate(&points, &mut want).unwrap();
            assert!(want.iter().any(|&t| t < 0) && want.iter().filter(|&&t| t >= 0).count() > points.len() / 2);
            let hint_sets: Vec<(&str, Vec<i32>)> = vec![
                ("right", want.clone()),
                ("next", want.iter().map(|&t| if t >= 0 { (t + 1) % n as i32 } else { t }).collect()),
                ("far", (0..points.len()).map(|i| ((i * 7919) % n) as i32).collect()),
                ("none", vec![-1; points.len()]),
                ("out of range", vec![n as i32 + 5; points.len()]),
            ];
            for (what, hints) in hint_sets {
                let mut got = vec![7; points.len()];
                assert!(gpu.hinted_locator().is_some());
                locate_from(&mut gpu, &points, &hints, &mut got).unwrap();
                assert_eq!(got, want, "{preset}: hints {what}");
            }
            let mut with_nan = points.clone();
            with_nan[3] = [f32::NAN, 0.0, 0.0];
            let mut got = vec![7; points.len()];
            locate_from(&mut gpu, &with_nan, &want, &mut got).unwrap();
            assert_eq!(got[3], -1);
            assert_eq!((&got[..3], &got[4..]), (&want[..3], &want[4..]), "{preset}: NaN point");
        }
        assert_eq!(ctx.validation_errors(), 0);
    }

    /// Where the answers must be certified on the file's data (a mesh stored in f64), and on
    /// kernels without the shader, there is no hinted locator: `locate_from` is `locate`.
    #[test]
    fn others_locate_afresh() {
        let Some(ctx) = test_context("hinted_others_locate_afresh") else { return };
        let mut raw = gen::generate(Shape::Fusion, 2_000, 3);
        raw.points64 = Some(raw.points.iter().map(|p| p.map(|c| f64::from(c) + 1e-9)).collect());
        let m64 = Arc::new(Mesh::new(raw, "fusion f64").unwrap());
        let mut gpu = VulkanLocator::new(ctx.clone(), m64, Kernel::SoftBvh, LocatorOptions::default()).unwrap();
        assert!(gpu.hinted_locator().is_none());
        if ctx.info().ray_tracing {
            let m = Arc::new(Mesh::new(gen::generate(Shape::Fusion, 2_000, 3), "fusion").unwrap());
            let mut rt = VulkanLocator::new(ctx.clone(), m, Kernel::RtBvh, LocatorOptions::default()).unwrap();
            assert!(rt.hinted_locator().is_none());
        }
    }
}
