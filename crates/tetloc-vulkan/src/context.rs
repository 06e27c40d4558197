//! Instance and device: discovery (`devices()`), selection, the optional validation layer
//! with an error-counting messenger, and the few device properties the kernels need.

use crate::error::{VkError, VkResult};
use ash::vk;
use std::ffi::{c_void, CStr};
use std::io::Write as _;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// What `devices()` reports about one Vulkan device.
#[derive(Clone, Debug)]
pub struct DeviceInfo {
    /// Index to pass to [`Context::new`].
    pub index: usize,
    pub name: String,
    /// Driver name and version, e.g. "NVIDIA 580.159.04" or "llvmpipe Mesa 25.0.7".
    pub driver: String,
    /// "discrete", "integrated", "virtual", "cpu" or "other".
    pub device_type: &'static str,
    /// The device's Vulkan version, e.g. "1.3.289".
    pub api_version: String,
    /// Ray-tracing pipelines and acceleration structures are available (the `rt-*` kernels).
    pub ray_tracing: bool,
    /// Device-local memory, summed over heaps.
    pub memory_bytes: u64,
    /// `shaderFloat64`: the exact f64 fallback of the point-in-tet test runs on the GPU. Without
    /// it, kernels use the documented pure-f32 test (watertight, not exact near faces).
    pub float64: bool,
    /// The compute queue has timestamps (needed by benchmarks).
    pub timestamps: bool,
    /// shaderStorageBufferArrayNonUniformIndexing (and ...DynamicIndexing): the shaders read
    /// arrays split over several buffers (larger than one buffer may be) and a launch's
    /// fields (an array of buffers) through it.
    pub nonuniform_buffers: bool,
    /// `VkPhysicalDeviceIDProperties::deviceUUID`: CUDA and NVML name the same GPU by it.
    pub uuid: [u8; 16],
}

/// How to create a [`Context`].
#[derive(Clone, Debug)]
pub struct ContextOptions {
    /// Device index from [`devices()`]; `None` picks the best (discrete GPU with ray tracing first).
    pub device_index: Option<usize>,
    /// Turn on `VK_LAYER_KHRONOS_validation` when it is installed. Default: the environment
    /// variable `TETLOC_VK_VALIDATION` is set to something other than `0`.
    pub validation: bool,
    /// Where the compiled pipelines are kept between runs (a file a device in this directory:
    /// the next process reuses them instead of compiling again, whatever the driver caches);
    /// `None`: not kept. Default: `tetloc_core::cache::dir()`, unless the environment variable
    /// `TETLOC_PIPELINE_CACHE` is `0`.
    pub pipeline_cache_dir: Option<std::path::PathBuf>,
}

impl Default for ContextOptions {
    fn default() -> Self {
        let validation = std::env::var("TETLOC_VK_VALIDATION").map(|v| !v.is_empty() && v != "0").unwrap_or(false);
        let keep = std::env::var("TETLOC_PIPELINE_CACHE").map_or(true, |v| v != "0");
        let pipeline_cache_dir = if keep { tetloc_core::cache::dir() } else { None };
        ContextOptions { device_index: None, validation, pipeline_cache_dir }
    }
}

/// The first bytes of a pipeline cache file ([`tetloc_core::cache::frame`]).
const PIPELINE_CACHE_MAGIC: &[u8; 8] = b"TLPIPES1";

/// The pipeline cache file of the device with `uuid` in `dir`.
fn pipeline_cache_file(dir: &std::path::Path, uuid: &[u8; 16]) -> std::path::PathBuf {
    let hex: String = uuid.iter().map(|b| format!("{b:02x}")).collect();
    dir.join(format!("pipelines-{hex}.bin"))
}

/// Ray-tracing function tables and properties, present when the device has ray tracing.
pub(crate) struct RayTracing {
    pub accel: ash::khr::acceleration_structure::Device,
    pub pipeline: ash::khr::ray_tracing_pipeline::Device,
    pub handle_size: u32,
    pub handle_alignment: u32,
    pub base_alignment: u32,
    pub max_dispatch: u32,
    pub scratch_alignment: u32,
}

/// Device limits the backend checks against.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Limits {
    pub max_storage_buffer_range: u64,
    pub max_workgroup_count: [u32; 3],
    pub max_workgroup_size: [u32; 3],
    pub timestamp_period_ns: f64,
    pub timestamp_valid_bits: u32,
    pub max_allocation: u64,
}

/// The function tables of `VK_KHR_external_memory_fd` and `VK_KHR_external_semaphore_fd`
/// (each enabled where present), and whether timeline semaphores are on.
pub(crate) struct ExternalFd {
    pub memory: Option<ash::khr::external_memory_fd::Device>,
    pub semaphore: Option<ash::khr::external_semaphore_fd::Device>,
    pub timeline: bool,
    /// For the external-memory and -semaphore capability queries.
    pub physical: vk::PhysicalDevice,
}

/// What `open_device` makes: the device, its queue family, ray tracing, limits, the probe's
/// information and the fd-sharing tables.
type Opened = (ash::Device, u32, Option<RayTracing>, Limits, DeviceInfo, Option<ExternalFd>);

/// Counts validation errors reported through the debug messenger.
struct Messenger {
    errors: AtomicUsize,
}

/// A Vulkan instance and logical device, shared (`Arc`) by the locators that run on it.
pub struct Context {
    pub(crate) instance: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    messenger: Box<Messenger>,
    pub(crate) device: ash::Device,
    pub(crate) queue: Mutex<vk::Queue>,
    pub(crate) queue_family: u32,
    pub(crate) memory_properties: vk::PhysicalDeviceMemoryProperties,
    pub(crate) rt: Option<RayTracing>,
    pub(crate) limits: Limits,
    /// The device UUID (NVML names the same GPU by it).
    pub(crate) uuid: [u8; 16],
    /// Memory and semaphores shared with other APIs (CUDA) through opaque fds, when the device
    /// has the extensions (`external.rs`).
    pub(crate) external: Option<ExternalFd>,
    /// Every pipeline of this process is made through it, so making one again (the stream
    /// pipeline of each batch of lines, a locator built again on the same mesh) reuses the
    /// first compilation, whether or not the driver keeps a cache of its own.
    pub(crate) pipeline_cache: vk::PipelineCache,
    /// Where the cache is kept between runs, and the checksum of what is there (written back
    /// when this process made pipelines since: [`Context::save_pipeline_cache`]).
    pipeline_cache_file: Option<(std::path::PathBuf, Mutex<u64>)>,
    /// Pipelines were made since the cache was last saved.
    pipelines_made: std::sync::atomic::AtomicBool,
    /// Bytes of kept pipelines this context started from (0: none, or none that passed).
    pipeline_cache_loaded: usize,
    info: DeviceInfo,
    validation: bool,
    // Last: the loader library must outlive every Vulkan object above.
    _entry: ash::Entry,
}

fn load_entry() -> VkResult<ash::Entry> {
    // SAFETY: loading the system's Vulkan loader; its initialisation has no preconditions.
    unsafe { ash::Entry::load() }.map_err(|e| VkError::NoLoader(e.to_string()))
}

fn create_instance(entry: &ash::Entry, validation: bool) -> VkResult<(ash::Instance, bool)> {
    // SAFETY: plain queries and instance creation with valid, live create-info structures.
    unsafe {
        let version = entry.try_enumerate_instance_version().ok().flatten().unwrap_or(vk::API_VERSION_1_0);
        if version < vk::API_VERSION_1_2 {
            return Err(VkError::Unsupported {
                device: "Vulkan loader".into(),
                reason: format!("Vulkan 1.2 is required; the loader supports {}", version_string(version)),
            });
        }
        let layers_present = validation
            && entry
                .enumerate_instance_layer_properties()
                .map(|ls| ls.iter().any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER)))
                .unwrap_or(false);
        let app =
            vk::ApplicationInfo::default().application_name(c"tetloc").api_version(version.min(vk::API_VERSION_1_3));
        let layers = [VALIDATION_LAYER.as_ptr()];
        let exts = [ash::ext::debug_utils::NAME.as_ptr()];
        let mut info = vk::InstanceCreateInfo::default().application_info(&app);
        if layers_present {
            info = info.enabled_layer_names(&layers).enabled_extension_names(&exts);
        }
        let instance = entry.create_instance(&info, None).map_err(VkError::vk("vkCreateInstance"))?;
        Ok((instance, layers_present))
    }
}

fn version_string(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

/// What we learn about a physical device before creating a logical one.
struct Probe {
    info: DeviceInfo,
    uuid: [u8; 16],
    api: u32,
    queue_family: Option<u32>,
    timestamp_valid_bits: u32,
    /// `VK_KHR_external_memory_fd` and `VK_KHR_external_semaphore_fd` are present.
    memory_fd: bool,
    semaphore_fd: bool,
    /// The `timelineSemaphore` feature (Vulkan 1.2).
    timeline: bool,
}

fn probe(instance: &ash::Instance, index: usize, pd: vk::PhysicalDevice) -> Probe {
    // SAFETY: queries on a physical device enumerated from this instance; every chained
    // struct is only chained when its extension is supported.
    unsafe {
        let mut driver = vk::PhysicalDeviceDriverProperties::default();
        let mut id = vk::PhysicalDeviceIDProperties::default();
        let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver).push_next(&mut id);
        instance.get_physical_device_properties2(pd, &mut props2);
        let props = props2.properties;
        let exts = instance.enumerate_device_extension_properties(pd).unwrap_or_default();
        let has = |name: &CStr| exts.iter().any(|e| e.extension_name_as_c_str() == Ok(name));
        let rt_exts = has(ash::khr::acceleration_structure::NAME)
            && has(ash::khr::ray_tracing_pipeline::NAME)
            && has(ash::khr::deferred_host_operations::NAME);
        let (memory_fd, semaphore_fd) =
            (has(ash::khr::external_memory_fd::NAME), has(ash::khr::external_semaphore_fd::NAME));

        let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut f_as = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
        let mut f_rt = vk::PhysicalDeviceRayTracingPipelineFeaturesKHR::default();
        let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f12);
        if rt_exts {
            f2 = f2.push_next(&mut f_as).push_next(&mut f_rt);
        }
        instance.get_physical_device_features2(pd, &mut f2);
        let float64 = f2.features.shader_float64 == vk::TRUE;
        let dynamic_buffers = f2.features.shader_storage_buffer_array_dynamic_indexing == vk::TRUE;
        let ray_tracing = rt_exts
            && f_as.acceleration_structure == vk::TRUE
            && f_rt.ray_tracing_pipeline == vk::TRUE
            && f12.buffer_device_address == vk::TRUE;

        let families = instance.get_physical_device_queue_family_properties(pd);
        // A compute queue with timestamps if there is one; else any compute queue.
        let compute = |f: &vk::QueueFamilyProperties| f.queue_flags.contains(vk::QueueFlags::COMPUTE);
        let queue_family = families
            .iter()
            .position(|f| compute(f) && f.timestamp_valid_bits > 0)
            .or_else(|| families.iter().position(compute))
            .map(|i| i as u32);
        let timestamp_valid_bits = queue_family.map_or(0, |q| families[q as usize].timestamp_valid_bits);

        let mem = instance.get_physical_device_memory_properties(pd);
        let memory_bytes = mem.memory_heaps[..mem.memory_heap_count as usize]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .sum();
        let device_type = match props.device_type {
            vk::PhysicalDeviceType::DISCRETE_GPU => "discrete",
            vk::PhysicalDeviceType::INTEGRATED_GPU => "integrated",
            vk::PhysicalDeviceType::VIRTUAL_GPU => "virtual",
            vk::PhysicalDeviceType::CPU => "cpu",
            _ => "other",
        };
        let cstr = |s: Result<&CStr, _>| s.map(|s: &CStr| s.to_string_lossy().into_owned()).unwrap_or_default();
        let driver_name = cstr(driver.driver_name_as_c_str());
        let driver_info = cstr(driver.driver_info_as_c_str());
        Probe {
            info: DeviceInfo {
                index,
                name: cstr(props.device_name_as_c_str()),
                driver: format!("{driver_name} {driver_info}").trim().to_string(),
                device_type,
                api_version: version_string(props.api_version),
                ray_tracing,
                memory_bytes,
                float64,
                timestamps: timestamp_valid_bits > 0,
                // Arrays of buffers indexed by a lane's value (split arrays) or by a loop's
                // (the fields of one launch: dynamically uniform).
                nonuniform_buffers: f12.shader_storage_buffer_array_non_uniform_indexing == vk::TRUE && dynamic_buffers,
                uuid: id.device_uuid,
            },
            uuid: id.device_uuid,
            api: props.api_version,
            queue_family,
            timestamp_valid_bits,
            memory_fd,
            semaphore_fd,
            timeline: f12.timeline_semaphore == vk::TRUE,
        }
    }
}

fn enumerate(instance: &ash::Instance) -> VkResult<Vec<(vk::PhysicalDevice, Probe)>> {
    // SAFETY: enumeration on a live instance.
    let pds = unsafe { instance.enumerate_physical_devices() }.map_err(VkError::vk("vkEnumeratePhysicalDevices"))?;
    Ok(pds.into_iter().enumerate().map(|(i, pd)| (pd, probe(instance, i, pd))).collect())
}

/// Lists the Vulkan devices this machine exposes. A missing loader is an error; a loader
/// without devices gives an empty list.
/// The unit tests' context: validating, on the default device; `None` (after printing
/// SKIPPED) where this machine has no Vulkan, except in CI, where that fails the test.
#[cfg(test)]
pub(crate) fn test_context(test: &str) -> Option<Arc<Context>> {
    match Context::with_options(ContextOptions { device_index: None, validation: true, pipeline_cache_dir: None }) {
        Ok(c) => Some(c),
        Err(e @ (VkError::NoLoader(_) | VkError::NoDevice)) if !tetloc_testdata::in_ci() => {
            eprintln!("{test}: {e}");
            tetloc_testdata::skip(test, "no Vulkan device");
            None
        }
        Err(e) => panic!("{test}: {e}"),
    }
}

pub fn devices() -> VkResult<Vec<DeviceInfo>> {
    let entry = load_entry()?;
    let (instance, _) = create_instance(&entry, false)?;
    let list = enumerate(&instance);
    // SAFETY: no objects were created from this instance.
    unsafe { instance.destroy_instance(None) };
    Ok(list?.into_iter().map(|(_, p)| p.info).collect())
}

unsafe extern "system" fn on_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: `user` is the boxed `Messenger` owned by the Context, which outlives the
    // messenger; `data` is valid for the duration of the callback.
    unsafe {
        if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
            (*(user as *const Messenger)).errors.fetch_add(1, Ordering::SeqCst);
            let msg = if data.is_null() || (*data).p_message.is_null() {
                "(no message)".into()
            } else {
                CStr::from_ptr((*data).p_message).to_string_lossy()
            };
            let _ = writeln!(std::io::stderr(), "tetloc-vulkan: validation error: {msg}");
        }
    }
    vk::FALSE
}

impl Context {
    /// Bytes of compiled pipelines kept by an earlier process that this context started from
    /// (0: none kept, or a file that failed its checks; the driver may still ignore them).
    pub fn kept_pipeline_bytes(&self) -> usize {
        self.pipeline_cache_loaded
    }

    /// Notes that a pipeline was made through [`Self::pipeline_cache`] (to be saved).
    pub(crate) fn note_pipeline_made(&self) {
        self.pipelines_made.store(true, std::sync::atomic::Ordering::Relaxed);
    }

    /// Writes the pipeline cache to its file where pipelines were made since it was last
    /// saved and its bytes changed: best effort (a cache that cannot be written is only a
    /// cache, and changes no answer).
    pub fn save_pipeline_cache(&self) {
        let Some((file, saved)) = &self.pipeline_cache_file else { return };
        if !self.pipelines_made.swap(false, std::sync::atomic::Ordering::Relaxed) {
            return;
        }
        let mut saved = saved.lock().unwrap_or_else(|p| p.into_inner());
        // SAFETY: the cache is alive (destroyed only in Drop, after this) and internally
        // synchronized.
        let Ok(data) = (unsafe { self.device.get_pipeline_cache_data(self.pipeline_cache) }) else { return };
        let sum = tetloc_core::cache::checksum(&data);
        if data.is_empty() || sum == *saved {
            return;
        }
        if tetloc_core::cache::write_atomically(file, &tetloc_core::cache::frame(PIPELINE_CACHE_MAGIC, &data)).is_ok() {
            *saved = sum;
        }
    }

    /// Opens device `device_index` (from [`devices()`]), or the best one when `None`.
    pub fn new(device_index: Option<usize>) -> VkResult<Arc<Context>> {
        Self::with_options(ContextOptions { device_index, ..Default::default() })
    }

    pub fn with_options(opts: ContextOptions) -> VkResult<Arc<Context>> {
        let entry = load_entry()?;
        let (instance, validation) = create_instance(&entry, opts.validation)?;
        // From here on, errors must destroy the instance: `Guard` does.
        struct Guard(Option<ash::Instance>);
        impl Drop for Guard {
            fn drop(&mut self) {
                if let Some(i) = self.0.take() {
                    // SAFETY: nothing else created from it survives an error return.
                    unsafe { i.destroy_instance(None) };
                }
            }
        }
        let mut guard = Guard(Some(instance));
        let instance = guard.0.as_ref().unwrap();
        let messenger = Box::new(Messenger { errors: AtomicUsize::new(0) });
        let debug = if validation {
            let du = ash::ext::debug_utils::Instance::new(&entry, instance);
            let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::GENERAL | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION,
                )
                .pfn_user_callback(Some(on_message))
                .user_data(&*messenger as *const Messenger as *mut c_void);
            // SAFETY: `messenger` is boxed and lives in the Context, after the messenger is destroyed.
            let m = unsafe { du.create_debug_utils_messenger(&info, None) }
                .map_err(VkError::vk("vkCreateDebugUtilsMessengerEXT"))?;
            Some((du, m))
        } else {
            None
        };
        let destroy_debug = |debug: &Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>| {
            if let Some((du, m)) = debug {
                // SAFETY: the messenger was created above and is not used afterwards.
                unsafe { du.destroy_debug_utils_messenger(*m, None) };
            }
        };

        let list = match enumerate(instance) {
            Ok(l) => l,
            Err(e) => {
                destroy_debug(&debug);
                return Err(e);
            }
        };
        let pick = match opts.device_index {
            Some(i) if i >= list.len() => Err(VkError::BadDeviceIndex { index: i, count: list.len() }),
            Some(i) => Ok(i),
            None if list.is_empty() => Err(VkError::NoDevice),
            None => {
                let score = |p: &Probe| {
                    let t = match p.info.device_type {
                        "discrete" => 4,
                        "integrated" => 3,
                        "virtual" => 2,
                        "cpu" => 1,
                        _ => 0,
                    };
                    (p.queue_family.is_some() && p.api >= vk::API_VERSION_1_2) as u32 * 100
                        + t * 2
                        + p.info.ray_tracing as u32
                };
                // Highest score, lowest index on ties.
                Ok(list.iter().enumerate().max_by_key(|(i, (_, p))| (score(p), usize::MAX - i)).unwrap().0)
            }
        };
        let result = pick.and_then(|i| {
            let (pd, probe) = &list[i];
            Self::open_device(instance, *pd, probe)
        });
        let (device, queue_family, rt, limits, info, external) = match result {
            Ok(r) => r,
            Err(e) => {
                destroy_debug(&debug);
                return Err(e);
            }
        };
        let (physical, uuid) = (list[info.index].0, list[info.index].1.uuid);
        // SAFETY: queries on the chosen device; queue 0 of the family was requested at creation.
        let (memory_properties, queue) = unsafe {
            (instance.get_physical_device_memory_properties(physical), device.get_device_queue(queue_family, 0))
        };
        // The pipelines an earlier process compiled on this device, where kept: checked by our
        // frame's checksum here, and by the driver against its own header (another driver's
        // data is ignored, and replaced when this process writes the cache back).
        let cache_file = opts.pipeline_cache_dir.as_deref().map(|d| pipeline_cache_file(d, &uuid));
        let kept = cache_file.as_deref().and_then(tetloc_core::cache::read);
        let initial = kept.as_deref().and_then(|k| tetloc_core::cache::unframe(PIPELINE_CACHE_MAGIC, k)).unwrap_or(&[]);
        let loaded = tetloc_core::cache::checksum(initial);
        let cache_info = vk::PipelineCacheCreateInfo::default().initial_data(initial);
        // SAFETY: a valid device; the initial data is the driver's own format or ignored by it
        // (the header it checks), and its bytes are the ones that were written.
        let pipeline_cache = match unsafe { device.create_pipeline_cache(&cache_info, None) } {
            Ok(c) => c,
            Err(result) => {
                // SAFETY: nothing was created from the device yet.
                unsafe { device.destroy_device(None) };
                destroy_debug(&debug);
                return Err(VkError::Vk { what: "vkCreatePipelineCache", result });
            }
        };
        Ok(Arc::new(Context {
            instance: guard.0.take().unwrap(),
            debug,
            messenger,
            device,
            queue: Mutex::new(queue),
            queue_family,
            memory_properties,
            rt,
            limits,
            uuid,
            external,
            pipeline_cache,
            pipeline_cache_file: cache_file.map(|f| (f, Mutex::new(loaded))),
            pipelines_made: std::sync::atomic::AtomicBool::new(false),
            pipeline_cache_loaded: initial.len(),
            info,
            validation,
            _entry: entry,
        }))
    }

    fn open_device(instance: &ash::Instance, pd: vk::PhysicalDevice, probe: &Probe) -> VkResult<Opened> {
        let info = probe.info.clone();
        if probe.api < vk::API_VERSION_1_2 {
            return Err(VkError::Unsupported {
                device: info.name,
                reason: format!("Vulkan 1.2 is required; the device supports {}", info.api_version),
            });
        }
        let Some(queue_family) = probe.queue_family else {
            return Err(VkError::Unsupported { device: info.name, reason: "no compute queue".into() });
        };
        let priorities = [1.0f32];
        let queues =
            [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family).queue_priorities(&priorities)];
        let mut exts = vec![];
        if info.ray_tracing {
            exts.extend([
                ash::khr::acceleration_structure::NAME.as_ptr(),
                ash::khr::ray_tracing_pipeline::NAME.as_ptr(),
                ash::khr::deferred_host_operations::NAME.as_ptr(),
            ]);
        }
        if probe.memory_fd {
            exts.push(ash::khr::external_memory_fd::NAME.as_ptr());
        }
        if probe.semaphore_fd {
            exts.push(ash::khr::external_semaphore_fd::NAME.as_ptr());
        }
        let features = vk::PhysicalDeviceFeatures::default()
            .shader_float64(info.float64)
            .shader_storage_buffer_array_dynamic_indexing(info.nonuniform_buffers);
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default()
            .buffer_device_address(info.ray_tracing)
            .shader_storage_buffer_array_non_uniform_indexing(info.nonuniform_buffers)
            .timeline_semaphore(probe.timeline);
        let mut f_as = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
        let mut f_rt = vk::PhysicalDeviceRayTracingPipelineFeaturesKHR::default().ray_tracing_pipeline(true);
        let mut create = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_extension_names(&exts)
            .enabled_features(&features)
            .push_next(&mut f12);
        if info.ray_tracing {
            create = create.push_next(&mut f_as).push_next(&mut f_rt);
        }
        // SAFETY: the physical device belongs to `instance`; features and extensions were
        // checked to be supported in `probe`.
        unsafe {
            let device = instance.create_device(pd, &create, None).map_err(VkError::vk("vkCreateDevice"))?;
            let props = instance.get_physical_device_properties(pd);
            let mut p11 = vk::PhysicalDeviceMaintenance3Properties::default();
            let mut p_rt = vk::PhysicalDeviceRayTracingPipelinePropertiesKHR::default();
            let mut p_as = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
            let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut p11);
            if info.ray_tracing {
                p2 = p2.push_next(&mut p_rt).push_next(&mut p_as);
            }
            instance.get_physical_device_properties2(pd, &mut p2);
            let limits = Limits {
                max_storage_buffer_range: props.limits.max_storage_buffer_range as u64,
                max_workgroup_count: props.limits.max_compute_work_group_count,
                max_workgroup_size: props.limits.max_compute_work_group_size,
                timestamp_period_ns: props.limits.timestamp_period as f64,
                timestamp_valid_bits: probe.timestamp_valid_bits,
                max_allocation: p11.max_memory_allocation_size,
            };
            let rt = info.ray_tracing.then(|| RayTracing {
                accel: ash::khr::acceleration_structure::Device::new(instance, &device),
                pipeline: ash::khr::ray_tracing_pipeline::Device::new(instance, &device),
                handle_size: p_rt.shader_group_handle_size,
                handle_alignment: p_rt.shader_group_handle_alignment,
                base_alignment: p_rt.shader_group_base_alignment,
                max_dispatch: p_rt.max_ray_dispatch_invocation_count,
                scratch_alignment: p_as.min_acceleration_structure_scratch_offset_alignment,
            });
            let external = (probe.memory_fd || probe.semaphore_fd).then(|| ExternalFd {
                memory: probe.memory_fd.then(|| ash::khr::external_memory_fd::Device::new(instance, &device)),
                semaphore: probe.semaphore_fd.then(|| ash::khr::external_semaphore_fd::Device::new(instance, &device)),
                timeline: probe.semaphore_fd && probe.timeline,
                physical: pd,
            });
            Ok((device, queue_family, rt, limits, info, external))
        }
    }

    /// What [`devices()`] says about this context's device.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// True when the validation layer is on for this context.
    pub fn validation_enabled(&self) -> bool {
        self.validation
    }

    /// Validation errors reported so far (always 0 without the validation layer).
    pub fn validation_errors(&self) -> usize {
        self.messenger.errors.load(Ordering::SeqCst)
    }

    /// Index of a memory type allowed by `type_bits` with all of `want`, preferring one that
    /// also has `prefer`.
    pub(crate) fn memory_type(
        &self,
        type_bits: u32,
        want: vk::MemoryPropertyFlags,
        prefer: vk::MemoryPropertyFlags,
    ) -> VkResult<u32> {
        let mp = &self.memory_properties;
        let ok = |i: u32, f: vk::MemoryPropertyFlags| {
            type_bits & (1 << i) != 0 && mp.memory_types[i as usize].property_flags.contains(f)
        };
        (0..mp.memory_type_count)
            .find(|&i| ok(i, want | prefer))
            .or_else(|| (0..mp.memory_type_count).find(|&i| ok(i, want)))
            .ok_or(VkError::NoMemoryType(want))
    }

    pub(crate) fn device_name(&self) -> String {
        self.info.name.clone()
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        // SAFETY: every object created from this device is owned by a locator holding an
        // `Arc<Context>`, so all of them are gone when the last Arc drops.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.save_pipeline_cache();
            self.device.destroy_pipeline_cache(self.pipeline_cache, None);
            self.device.destroy_device(None);
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

#[cfg(test)]
mod pipeline_cache_tests {
    use super::*;
    use crate::{Kernel, LocatorOptions, VulkanLocator};
    use tetloc_core::locate::BatchLocator;

    /// A context on the test device keeping its pipelines in `dir` (`None`: no device, skipped).
    fn context_in(dir: &std::path::Path) -> Option<Arc<Context>> {
        let opts = ContextOptions { device_index: None, validation: true, pipeline_cache_dir: Some(dir.to_path_buf()) };
        match Context::with_options(opts) {
            Ok(c) => Some(c),
            Err(e @ (VkError::NoLoader(_) | VkError::NoDevice)) if !tetloc_testdata::in_ci() => {
                tetloc_testdata::skip("pipelines_are_kept_between_contexts", &e.to_string());
                None
            }
            Err(e) => panic!("{e}"),
        }
    }

    /// Locates a few points on a small mesh (compiling soft-bvh's pipelines).
    fn use_it(ctx: &Arc<Context>) {
        let m = Arc::new(
            tetloc_core::Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Fusion, 500, 1), "m").unwrap(),
        );
        let mut loc = VulkanLocator::new(ctx.clone(), m.clone(), Kernel::SoftBvh, LocatorOptions::default()).unwrap();
        let points: Vec<_> = (0..m.n_tets()).map(|t| m.tet_center(t)).collect();
        let mut ids = vec![0; points.len()];
        loc.locate(&points, &mut ids).unwrap();
        assert!(ids.iter().enumerate().all(|(t, &id)| id == t as i32));
    }

    /// The pipelines a context compiled are in its device's file once it is gone, and the next
    /// context starts from them; a torn, altered or foreign file is ignored (and replaced),
    /// never trusted.
    #[test]
    fn pipelines_are_kept_between_contexts() {
        let dir = std::env::temp_dir().join(format!("tetloc-pipelines-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let Some(ctx) = context_in(&dir) else { return };
        assert_eq!(ctx.pipeline_cache_loaded, 0);
        use_it(&ctx);
        let file = ctx.pipeline_cache_file.as_ref().unwrap().0.clone();
        drop(ctx);
        let kept = std::fs::read(&file).expect("the cache file is written");
        let payload = tetloc_core::cache::unframe(PIPELINE_CACHE_MAGIC, &kept).expect("a whole frame").len();
        assert!(payload > 0);
        let ctx = context_in(&dir).unwrap();
        assert_eq!(ctx.pipeline_cache_loaded, payload);
        use_it(&ctx);
        drop(ctx);
        // Altered bytes, a torn file, and a frame whose payload is no driver's: the context
        // starts empty (or the driver ignores the foreign header) and works.
        let mut altered = kept.clone();
        let at = altered.len() / 2;
        altered[at] ^= 0x55;
        let foreign = tetloc_core::cache::frame(PIPELINE_CACHE_MAGIC, &[0u8; 64]);
        for (what, bytes) in [("altered", altered), ("torn", kept[..kept.len() / 3].to_vec()), ("foreign", foreign)] {
            std::fs::write(&file, &bytes).unwrap();
            let ctx = context_in(&dir).unwrap();
            let expect = if what == "foreign" { 64 } else { 0 };
            assert_eq!(ctx.pipeline_cache_loaded, expect, "{what}");
            use_it(&ctx);
            assert_eq!(ctx.validation_errors(), 0, "{what}");
            drop(ctx);
            let again = std::fs::read(&file).unwrap();
            // The driver's data again (lavapipe keeps only its header; NVIDIA the pipelines).
            let len = tetloc_core::cache::unframe(PIPELINE_CACHE_MAGIC, &again).map(<[u8]>::len);
            assert_eq!(len, Some(payload), "{what}");
        }
        // A file larger than any cache is not read at all (sparse: no disk used).
        std::fs::File::create(&file).unwrap().set_len(tetloc_core::cache::MAX_FILE + 1).unwrap();
        let ctx = context_in(&dir).unwrap();
        assert_eq!(ctx.kept_pipeline_bytes(), 0);
        drop(ctx);
        // No temporary file is left beside it.
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left, [file.file_name().unwrap().to_os_string()]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
