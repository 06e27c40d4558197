//! Descriptor sets, shader modules with specialization constants, and the compute and
//! ray-tracing pipelines built from them (with the ray-tracing shader binding table).

use crate::context::Context;
use crate::device::{Device, Split};
use crate::error::{VkError, VkResult};
use crate::interface::{Params, MAX_CHUNKS};
use crate::memory::{Buffer, BufferDesc, MemKind};
use crate::shaders::Shader;
use ash::vk;
use std::sync::Arc;

/// What one binding of the descriptor set points at.
#[derive(Clone, Debug)]
pub(crate) enum Bound {
    /// Storage buffers: one, or the elements of an array binding in order.
    Buffers(Vec<vk::DescriptorBufferInfo>),
    Accel(vk::AccelerationStructureKHR),
}

/// A binding number and what it points at: the unit in which kernels describe their
/// structures (`Plan::bindings`) and pipelines declare and fill their descriptor sets.
#[derive(Clone, Debug)]
pub(crate) struct Binding {
    pub slot: u32,
    pub bound: Bound,
}

impl Binding {
    pub fn buffer(slot: u32, b: &Buffer) -> Binding {
        Binding { slot, bound: Bound::Buffers(vec![b.info()]) }
    }

    pub fn accel(slot: u32, a: vk::AccelerationStructureKHR) -> Binding {
        Binding { slot, bound: Bound::Accel(a) }
    }

    /// A split array: its first buffer at `lo`, the others (`unbound` past the last) at the
    /// array binding `hi`. `None`: the array is not used; everything is `unbound`.
    pub fn split(lo: u32, hi: u32, array: Option<&Split>, unbound: &Buffer) -> [Binding; 2] {
        let part = |k: usize| array.and_then(|a| a.parts.get(k)).unwrap_or(unbound).info();
        [
            Binding { slot: lo, bound: Bound::Buffers(vec![part(0)]) },
            Binding { slot: hi, bound: Bound::Buffers((1..MAX_CHUNKS as usize).map(part).collect()) },
        ]
    }

    /// The array binding `slot` of `len` buffers: `buffers`, then `unbound`.
    pub fn array(slot: u32, buffers: &[&Buffer], len: u32, unbound: &Buffer) -> Binding {
        let infos = (0..len as usize).map(|k| buffers.get(k).copied().unwrap_or(unbound).info()).collect();
        Binding { slot, bound: Bound::Buffers(infos) }
    }

    /// A split array bound whole at the array binding `slot` (MAX_CHUNKS buffers, `unbound`
    /// past its last; `None`: all `unbound`), as the GPU build declares its arrays.
    pub fn parts(slot: u32, array: Option<&Split>, unbound: &Buffer) -> Binding {
        let part = |k: usize| array.and_then(|a| a.parts.get(k)).unwrap_or(unbound).info();
        Binding { slot, bound: Bound::Buffers((0..MAX_CHUNKS as usize).map(part).collect()) }
    }

    fn layout(&self, stages: vk::ShaderStageFlags) -> vk::DescriptorSetLayoutBinding<'static> {
        let (ty, n) = match &self.bound {
            Bound::Buffers(infos) => (vk::DescriptorType::STORAGE_BUFFER, infos.len() as u32),
            Bound::Accel(_) => (vk::DescriptorType::ACCELERATION_STRUCTURE_KHR, 1),
        };
        vk::DescriptorSetLayoutBinding::default()
            .binding(self.slot)
            .descriptor_type(ty)
            .descriptor_count(n)
            .stage_flags(stages)
    }
}

/// One descriptor set (set 0) with its layout, pool and the pipeline layout around it.
pub(crate) struct Descriptors {
    ctx: Arc<Context>,
    set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    pub set: vk::DescriptorSet,
    pub layout: vk::PipelineLayout,
    pub stages: vk::ShaderStageFlags,
}

impl Descriptors {
    /// A set with a layout for `bindings` (visible to `stages`), pointed at what they name.
    pub fn new(ctx: &Arc<Context>, bindings: &[Binding], stages: vk::ShaderStageFlags) -> VkResult<Descriptors> {
        let dev = &ctx.device;
        let layout_bindings: Vec<_> = bindings.iter().map(|b| b.layout(stages)).collect();
        let mut sizes: Vec<vk::DescriptorPoolSize> = vec![];
        for b in &layout_bindings {
            match sizes.iter_mut().find(|s| s.ty == b.descriptor_type) {
                Some(s) => s.descriptor_count += b.descriptor_count,
                None => {
                    sizes.push(vk::DescriptorPoolSize { ty: b.descriptor_type, descriptor_count: b.descriptor_count })
                }
            }
        }
        let ranges =
            [vk::PushConstantRange { stage_flags: stages, offset: 0, size: std::mem::size_of::<Params>() as u32 }];
        let mut d = Descriptors {
            ctx: ctx.clone(),
            set_layout: vk::DescriptorSetLayout::null(),
            pool: vk::DescriptorPool::null(),
            set: vk::DescriptorSet::null(),
            layout: vk::PipelineLayout::null(),
            stages,
        };
        // SAFETY: valid create infos; Drop destroys whatever was created if a later step fails.
        unsafe {
            d.set_layout = dev
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings),
                    None,
                )
                .map_err(VkError::vk("vkCreateDescriptorSetLayout"))?;
            d.pool = dev
                .create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes), None)
                .map_err(VkError::vk("vkCreateDescriptorPool"))?;
            let layouts = [d.set_layout];
            d.set = dev
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default().descriptor_pool(d.pool).set_layouts(&layouts),
                )
                .map_err(VkError::vk("vkAllocateDescriptorSets"))?[0];
            d.layout = dev
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts).push_constant_ranges(&ranges),
                    None,
                )
                .map_err(VkError::vk("vkCreatePipelineLayout"))?;
        }
        d.write(bindings);
        Ok(d)
    }

    /// Points bindings (declared at creation) at what they name. The set must not be in use
    /// by a pending submission (every submission is waited for).
    pub fn write(&self, bindings: &[Binding]) {
        for b in bindings {
            let w = vk::WriteDescriptorSet::default().dst_set(self.set).dst_binding(b.slot);
            match &b.bound {
                Bound::Buffers(infos) => {
                    let w = w.descriptor_type(vk::DescriptorType::STORAGE_BUFFER).buffer_info(infos);
                    // SAFETY: the set is not in use by any pending submission; the buffers are alive.
                    unsafe { self.ctx.device.update_descriptor_sets(&[w], &[]) };
                }
                Bound::Accel(accel) => {
                    let handles = [*accel];
                    let mut info =
                        vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&handles);
                    let mut w = w.descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR).push_next(&mut info);
                    w.descriptor_count = 1;
                    // SAFETY: as above; the acceleration structure is alive.
                    unsafe { self.ctx.device.update_descriptor_sets(&[w], &[]) };
                }
            }
        }
    }
}

impl Drop for Descriptors {
    fn drop(&mut self) {
        // SAFETY: no pending work uses these objects; null handles are ignored by Vulkan.
        unsafe {
            let dev = &self.ctx.device;
            dev.destroy_pipeline_layout(self.layout, None);
            dev.destroy_descriptor_pool(self.pool, None);
            dev.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// Specialization constants, all 32-bit (int, uint, float and bool alike).
#[derive(Clone, Debug, Default)]
pub(crate) struct Spec {
    entries: Vec<vk::SpecializationMapEntry>,
    data: Vec<u8>,
}

impl Spec {
    pub fn set(mut self, id: u32, bits: u32) -> Spec {
        self.entries.push(vk::SpecializationMapEntry { constant_id: id, offset: self.data.len() as u32, size: 4 });
        self.data.extend_from_slice(&bits.to_le_bytes());
        self
    }

    /// These constants followed by `more`'s.
    pub fn concat(mut self, more: &Spec) -> Spec {
        let base = self.data.len() as u32;
        self.entries.extend(more.entries.iter().map(|e| vk::SpecializationMapEntry { offset: e.offset + base, ..*e }));
        self.data.extend_from_slice(&more.data);
        self
    }

    fn info(&self) -> vk::SpecializationInfo<'_> {
        vk::SpecializationInfo::default().map_entries(&self.entries).data(&self.data)
    }
}

/// The shaders of one pipeline: a compute shader, or the stages of a ray-tracing pipeline
/// (ray generation, miss, and a hit group: closest hit, and an intersection shader for
/// procedural (AABB) geometry). Each in its f64 and f32 variants, picked at creation.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Program {
    Compute(Shader),
    RayTracing { raygen: Shader, miss: Shader, closest_hit: Shader, intersection: Option<Shader> },
}

impl Program {
    pub fn ray_tracing(&self) -> bool {
        matches!(self, Program::RayTracing { .. })
    }

    /// The stages a descriptor set must be visible to.
    pub fn stages(&self) -> vk::ShaderStageFlags {
        match self {
            Program::Compute(_) => vk::ShaderStageFlags::COMPUTE,
            Program::RayTracing { .. } => {
                vk::ShaderStageFlags::RAYGEN_KHR
                    | vk::ShaderStageFlags::MISS_KHR
                    | vk::ShaderStageFlags::CLOSEST_HIT_KHR
                    | vk::ShaderStageFlags::INTERSECTION_KHR
            }
        }
    }

    /// The pipeline of this program for a device with (`f64`) or without the exact f64 test.
    pub fn pipeline(&self, dev: &mut Device, layout: vk::PipelineLayout, f64: bool, spec: &Spec) -> VkResult<Pipeline> {
        match *self {
            Program::Compute(shader) => compute_pipeline(dev.ctx(), layout, shader.pick(f64), spec),
            Program::RayTracing { raygen, miss, closest_hit, intersection } => {
                let shaders = RtShaders {
                    raygen: raygen.pick(f64),
                    miss: miss.pick(f64),
                    closest_hit: closest_hit.pick(f64),
                    intersection: intersection.map(|s| s.pick(f64)),
                };
                rt_pipeline(dev, layout, &shaders, spec)
            }
        }
    }
}

/// A shader module, destroyed on drop.
struct Module<'a> {
    dev: &'a ash::Device,
    module: vk::ShaderModule,
}

impl<'a> Module<'a> {
    fn new(dev: &'a ash::Device, spirv: &[u8]) -> VkResult<Module<'a>> {
        let words = ash::util::read_spv(&mut std::io::Cursor::new(spirv)).map_err(|_| VkError::Vk {
            what: "reading embedded SPIR-V",
            result: vk::Result::ERROR_INVALID_SHADER_NV,
        })?;
        // SAFETY: the words are SPIR-V produced by glslang at build time.
        let module = unsafe { dev.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None) }
            .map_err(VkError::vk("vkCreateShaderModule"))?;
        Ok(Module { dev, module })
    }
}

impl Drop for Module<'_> {
    fn drop(&mut self) {
        // SAFETY: modules may be destroyed once the pipelines using them are created.
        unsafe { self.dev.destroy_shader_module(self.module, None) };
    }
}

/// A pipeline (compute or ray tracing), with its shader binding table for ray tracing.
pub(crate) struct Pipeline {
    ctx: Arc<Context>,
    pub pipeline: vk::Pipeline,
    pub bind_point: vk::PipelineBindPoint,
    pub sbt: Option<Sbt>,
}

impl Pipeline {
    /// Records this compute pipeline over `n` invocations (one a point, in workgroups of
    /// `workgroup`) with descriptor set `desc` and push constants `push`, then a barrier: the
    /// launch of the shaders that bring their own descriptor set (stream, hinted).
    pub(crate) fn record_points(
        &self,
        r: &crate::device::Recording,
        desc: &Descriptors,
        push: &Params,
        n: usize,
        workgroup: u32,
    ) {
        // SAFETY: recording with a live pipeline, layout and descriptor set; the push constants
        // are the layout's range.
        unsafe {
            r.dev.cmd_bind_pipeline(r.cmd, self.bind_point, self.pipeline);
            r.dev.cmd_bind_descriptor_sets(r.cmd, self.bind_point, desc.layout, 0, &[desc.set], &[]);
            r.dev.cmd_push_constants(r.cmd, desc.layout, desc.stages, 0, bytemuck::bytes_of(push));
            r.dev.cmd_dispatch(r.cmd, (n as u32).div_ceil(workgroup), 1, 1);
        }
        r.barrier();
    }
}

/// The shader binding table: one record each for ray generation, miss and the hit group.
pub(crate) struct Sbt {
    _buf: Buffer,
    pub raygen: vk::StridedDeviceAddressRegionKHR,
    pub miss: vk::StridedDeviceAddressRegionKHR,
    pub hit: vk::StridedDeviceAddressRegionKHR,
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        // SAFETY: no pending work uses the pipeline.
        unsafe { self.ctx.device.destroy_pipeline(self.pipeline, None) };
    }
}

fn compute_pipeline(ctx: &Arc<Context>, layout: vk::PipelineLayout, spirv: &[u8], spec: &Spec) -> VkResult<Pipeline> {
    let dev = &ctx.device;
    let module = Module::new(dev, spirv)?;
    let spec_info = spec.info();
    let stage = vk::PipelineShaderStageCreateInfo::default()
        .stage(vk::ShaderStageFlags::COMPUTE)
        .module(module.module)
        .name(c"main")
        .specialization_info(&spec_info);
    let info = vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout);
    // SAFETY: valid module, layout and specialization data.
    let pipeline = unsafe { dev.create_compute_pipelines(ctx.pipeline_cache, &[info], None) }
        .map_err(|(_, r)| VkError::Vk { what: "vkCreateComputePipelines", result: r })?[0];
    ctx.note_pipeline_made();
    Ok(Pipeline { ctx: ctx.clone(), pipeline, bind_point: vk::PipelineBindPoint::COMPUTE, sbt: None })
}

/// The SPIR-V of a ray-tracing pipeline's stages.
struct RtShaders<'a> {
    pub raygen: &'a [u8],
    pub miss: &'a [u8],
    pub closest_hit: &'a [u8],
    pub intersection: Option<&'a [u8]>,
}

fn align_up(x: u64, a: u64) -> u64 {
    x.div_ceil(a) * a
}

fn rt_pipeline(
    device: &mut Device,
    layout: vk::PipelineLayout,
    shaders: &RtShaders,
    spec: &Spec,
) -> VkResult<Pipeline> {
    let ctx = device.ctx().clone();
    let rt = ctx.rt.as_ref().expect("ray-tracing pipeline on a device without ray tracing");
    let dev = &ctx.device;
    let rgen = Module::new(dev, shaders.raygen)?;
    let miss = Module::new(dev, shaders.miss)?;
    let chit = Module::new(dev, shaders.closest_hit)?;
    let rint = shaders.intersection.map(|s| Module::new(dev, s)).transpose()?;
    let spec_info = spec.info();
    let stage = |flags, m: &Module| {
        vk::PipelineShaderStageCreateInfo::default()
            .stage(flags)
            .module(m.module)
            .name(c"main")
            .specialization_info(&spec_info)
    };
    let mut stages = vec![
        stage(vk::ShaderStageFlags::RAYGEN_KHR, &rgen),
        stage(vk::ShaderStageFlags::MISS_KHR, &miss),
        stage(vk::ShaderStageFlags::CLOSEST_HIT_KHR, &chit),
    ];
    if let Some(m) = &rint {
        stages.push(stage(vk::ShaderStageFlags::INTERSECTION_KHR, m));
    }
    let general = |i: u32| {
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(vk::RayTracingShaderGroupTypeKHR::GENERAL)
            .general_shader(i)
            .closest_hit_shader(vk::SHADER_UNUSED_KHR)
            .any_hit_shader(vk::SHADER_UNUSED_KHR)
            .intersection_shader(vk::SHADER_UNUSED_KHR)
    };
    let hit = vk::RayTracingShaderGroupCreateInfoKHR::default()
        .ty(if rint.is_some() {
            vk::RayTracingShaderGroupTypeKHR::PROCEDURAL_HIT_GROUP
        } else {
            vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP
        })
        .general_shader(vk::SHADER_UNUSED_KHR)
        .closest_hit_shader(2)
        .any_hit_shader(vk::SHADER_UNUSED_KHR)
        .intersection_shader(if rint.is_some() { 3 } else { vk::SHADER_UNUSED_KHR });
    let groups = [general(0), general(1), hit];
    let info = vk::RayTracingPipelineCreateInfoKHR::default()
        .stages(&stages)
        .groups(&groups)
        .max_pipeline_ray_recursion_depth(1)
        .layout(layout);
    // SAFETY: valid modules, groups and layout.
    let pipeline = unsafe {
        rt.pipeline.create_ray_tracing_pipelines(vk::DeferredOperationKHR::null(), ctx.pipeline_cache, &[info], None)
    }
    .map_err(|(_, r)| VkError::Vk { what: "vkCreateRayTracingPipelinesKHR", result: r })?[0];
    ctx.note_pipeline_made();
    let pipeline =
        Pipeline { ctx: ctx.clone(), pipeline, bind_point: vk::PipelineBindPoint::RAY_TRACING_KHR, sbt: None };

    // Shader binding table: each region starts at the base alignment.
    let handle = rt.handle_size as usize;
    // SAFETY: the pipeline has exactly 3 groups.
    let handles = unsafe { rt.pipeline.get_ray_tracing_shader_group_handles(pipeline.pipeline, 0, 3, 3 * handle) }
        .map_err(VkError::vk("vkGetRayTracingShaderGroupHandlesKHR"))?;
    let stride = align_up(handle as u64, rt.handle_alignment as u64);
    let region = align_up(stride, rt.base_alignment as u64);
    let mut table = vec![0u8; 3 * region as usize];
    for g in 0..3 {
        table[g * region as usize..][..handle].copy_from_slice(&handles[g * handle..][..handle]);
    }
    let usage = vk::BufferUsageFlags::SHADER_BINDING_TABLE_KHR
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
        | vk::BufferUsageFlags::TRANSFER_DST;
    // The table's address must be aligned too: over-allocate and start at an aligned offset.
    let pad = rt.base_alignment as u64;
    let size = table.len() as u64 + pad;
    let buf =
        device.create_buffer(BufferDesc::device(MemKind::Structure, size, usage), "shader binding table", None)?;
    let base = align_up(buf.address, pad);
    device.write(&buf, base - buf.address, &table)?;
    let at = |g: u64, size: u64| vk::StridedDeviceAddressRegionKHR { device_address: base + g * region, stride, size };
    let sbt = Sbt { raygen: at(0, stride), miss: at(1, stride), hit: at(2, stride), _buf: buf };
    let mut pipeline = pipeline;
    pipeline.sbt = Some(sbt);
    Ok(pipeline)
}
