//! Descriptor sets, shader modules with specialization constants, and the compute and
//! ray-tracing pipelines built from them (with the ray-tracing shader binding table).

use crate::context::Context;
use crate::error::{VkError, VkResult};
use crate::gpu_types::Params;
use crate::memory::{Buffer, Commands, Location, MemKind, SharedTracker, Staging};
use ash::vk;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

/// One descriptor set (set 0) with its layout, pool and the pipeline layout around it.
pub(crate) struct Descriptors {
    ctx: Arc<Context>,
    set_layout: vk::DescriptorSetLayout,
    pool: vk::DescriptorPool,
    pub set: vk::DescriptorSet,
    pub layout: vk::PipelineLayout,
    pub stages: vk::ShaderStageFlags,
    /// Storage-buffer bindings written so far, by binding.
    written: Mutex<BTreeMap<u32, Vec<vk::DescriptorBufferInfo>>>,
}

impl Descriptors {
    /// `bindings`: (binding, type, number of descriptors: 1, or an array).
    pub fn new(
        ctx: &Arc<Context>,
        bindings: &[(u32, vk::DescriptorType, u32)],
        stages: vk::ShaderStageFlags,
    ) -> VkResult<Descriptors> {
        let dev = &ctx.device;
        let layout_bindings: Vec<_> = bindings
            .iter()
            .map(|&(b, t, n)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(t)
                    .descriptor_count(n)
                    .stage_flags(stages)
            })
            .collect();
        let mut sizes: Vec<vk::DescriptorPoolSize> = vec![];
        for &(_, t, n) in bindings {
            match sizes.iter_mut().find(|s| s.ty == t) {
                Some(s) => s.descriptor_count += n,
                None => sizes.push(vk::DescriptorPoolSize { ty: t, descriptor_count: n }),
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
            written: Mutex::default(),
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
        Ok(d)
    }

    /// Points storage-buffer bindings at buffers. The set must not be in use (we always wait).
    pub fn write_buffers(&self, writes: &[(u32, &Buffer)]) -> VkResult<()> {
        for (binding, b) in writes {
            self.write_buffer_array(*binding, &[*b])?;
        }
        Ok(())
    }

    /// Points the elements 0.. of an array binding at `buffers`, in order.
    pub fn write_buffer_array(&self, binding: u32, buffers: &[&Buffer]) -> VkResult<()> {
        let limit = self.ctx.limits.max_storage_buffer_range;
        if let Some(b) = buffers.iter().find(|b| b.size > limit) {
            return Err(VkError::TooLarge {
                name: b.name.clone(),
                bytes: b.size,
                limit,
                what: "maxStorageBufferRange",
            });
        }
        let infos: Vec<vk::DescriptorBufferInfo> = buffers.iter().map(|b| b.info()).collect();
        self.write_infos(&[(binding, infos)]);
        Ok(())
    }

    /// Points storage-buffer bindings (each an array of one or more) at buffers given by their
    /// descriptor infos (buffers of another object, already checked against the range limit
    /// when that object bound them). Remembered for [`Descriptors::buffer_bindings`].
    pub fn write_infos(&self, writes: &[(u32, Vec<vk::DescriptorBufferInfo>)]) {
        let w: Vec<_> = writes
            .iter()
            .map(|(binding, infos)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(self.set)
                    .dst_binding(*binding)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .buffer_info(infos)
            })
            .collect();
        // SAFETY: the set is not in use by any pending submission.
        unsafe { self.ctx.device.update_descriptor_sets(&w, &[]) };
        let mut written = self.written.lock().unwrap_or_else(|e| e.into_inner());
        for (binding, infos) in writes {
            written.insert(*binding, infos.clone());
        }
    }

    /// Every storage-buffer binding written so far with what it points at, so that another
    /// pipeline can bind the same buffers (the volume marcher binds a locator's).
    pub fn buffer_bindings(&self) -> Vec<(u32, Vec<vk::DescriptorBufferInfo>)> {
        let written = self.written.lock().unwrap_or_else(|e| e.into_inner());
        written.iter().map(|(b, infos)| (*b, infos.clone())).collect()
    }

    pub fn write_accel(&self, binding: u32, accel: vk::AccelerationStructureKHR) {
        let handles = [accel];
        let mut info = vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&handles);
        let mut w = vk::WriteDescriptorSet::default()
            .dst_set(self.set)
            .dst_binding(binding)
            .descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
            .push_next(&mut info);
        w.descriptor_count = 1;
        // SAFETY: as in write_buffers.
        unsafe { self.ctx.device.update_descriptor_sets(&[w], &[]) };
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

    fn info(&self) -> vk::SpecializationInfo<'_> {
        vk::SpecializationInfo::default().map_entries(&self.entries).data(&self.data)
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

pub(crate) fn compute_pipeline(
    ctx: &Arc<Context>,
    layout: vk::PipelineLayout,
    spirv: &[u8],
    spec: &Spec,
) -> VkResult<Pipeline> {
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
    let pipeline = unsafe { dev.create_compute_pipelines(vk::PipelineCache::null(), &[info], None) }
        .map_err(|(_, r)| VkError::Vk { what: "vkCreateComputePipelines", result: r })?[0];
    Ok(Pipeline { ctx: ctx.clone(), pipeline, bind_point: vk::PipelineBindPoint::COMPUTE, sbt: None })
}

/// The shaders of a ray-tracing pipeline: ray generation, miss, closest hit, and an
/// intersection shader for procedural (AABB) geometry.
pub(crate) struct RtShaders<'a> {
    pub raygen: &'a [u8],
    pub miss: &'a [u8],
    pub closest_hit: &'a [u8],
    pub intersection: Option<&'a [u8]>,
}

fn align_up(x: u64, a: u64) -> u64 {
    x.div_ceil(a) * a
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn rt_pipeline(
    ctx: &Arc<Context>,
    tracker: &SharedTracker,
    staging: &mut Staging,
    cmds: &mut Commands,
    layout: vk::PipelineLayout,
    shaders: &RtShaders,
    spec: &Spec,
) -> VkResult<Pipeline> {
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
        rt.pipeline.create_ray_tracing_pipelines(
            vk::DeferredOperationKHR::null(),
            vk::PipelineCache::null(),
            &[info],
            None,
        )
    }
    .map_err(|(_, r)| VkError::Vk { what: "vkCreateRayTracingPipelinesKHR", result: r })?[0];
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
    let buf = Buffer::new(ctx, tracker, "shader binding table", MemKind::Structure, size, usage, Location::Device)?;
    let base = align_up(buf.address, pad);
    staging.upload(cmds, &buf, base - buf.address, &table)?;
    let at = |g: u64, size: u64| vk::StridedDeviceAddressRegionKHR { device_address: base + g * region, stride, size };
    let sbt = Sbt { raygen: at(0, stride), miss: at(1, stride), hit: at(2, stride), _buf: buf };
    let mut pipeline = pipeline;
    pipeline.sbt = Some(sbt);
    Ok(pipeline)
}
