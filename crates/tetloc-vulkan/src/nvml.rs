//! Board power through NVML, when the NVIDIA management library is installed: opened at
//! run time with dlopen, so that the backend neither links nor needs it.

use std::ffi::{c_char, c_int, c_uint, c_void, CStr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

type Device = *mut c_void;
type InitFn = unsafe extern "C" fn() -> c_int;
type CountFn = unsafe extern "C" fn(*mut c_uint) -> c_int;
type HandleFn = unsafe extern "C" fn(c_uint, *mut Device) -> c_int;
type UuidFn = unsafe extern "C" fn(Device, *mut c_char, c_uint) -> c_int;
type PowerFn = unsafe extern "C" fn(Device, *mut c_uint) -> c_int;

/// One NVML device's power reading.
pub(crate) struct Nvml {
    _lib: libloading::Library,
    shutdown: unsafe extern "C" fn() -> c_int,
    power: PowerFn,
    device: Device,
}

// SAFETY: NVML is thread-safe; the handle stays valid until nvmlShutdown in Drop.
unsafe impl Send for Nvml {}
// SAFETY: as for Send: NVML's calls may come from any thread at once.
unsafe impl Sync for Nvml {}

/// NVML's text form of a GPU UUID: "GPU-" and the 16 bytes as 8-4-4-4-12 hex digits.
fn uuid_text(uuid: &[u8; 16]) -> String {
    let h: String = uuid.iter().map(|b| format!("{b:02x}")).collect();
    format!("GPU-{}-{}-{}-{}-{}", &h[0..8], &h[8..12], &h[12..16], &h[16..20], &h[20..32])
}

impl Nvml {
    /// Opens NVML and finds the device with this Vulkan device UUID (or the only device).
    /// `None` when NVML is absent or the device is not an NVIDIA GPU NVML knows.
    pub fn open(uuid: &[u8; 16]) -> Option<Nvml> {
        // SAFETY: loading a system library and calling its documented C entry points with
        // valid pointers; every call's status is checked.
        unsafe {
            let lib = libloading::Library::new("libnvidia-ml.so.1").ok()?;
            let init: InitFn = *lib.get::<InitFn>(b"nvmlInit_v2\0").ok()?;
            let shutdown = *lib.get::<InitFn>(b"nvmlShutdown\0").ok()?;
            let count: CountFn = *lib.get::<CountFn>(b"nvmlDeviceGetCount_v2\0").ok()?;
            let handle: HandleFn = *lib.get::<HandleFn>(b"nvmlDeviceGetHandleByIndex_v2\0").ok()?;
            let get_uuid: UuidFn = *lib.get::<UuidFn>(b"nvmlDeviceGetUUID\0").ok()?;
            let power: PowerFn = *lib.get::<PowerFn>(b"nvmlDeviceGetPowerUsage\0").ok()?;
            if init() != 0 {
                return None;
            }
            let mut n = 0;
            let want = uuid_text(uuid);
            let mut found = None;
            if count(&mut n) == 0 {
                for i in 0..n {
                    let mut d: Device = std::ptr::null_mut();
                    let mut buf = [0 as c_char; 96];
                    if handle(i, &mut d) == 0 && get_uuid(d, buf.as_mut_ptr(), buf.len() as c_uint) == 0 {
                        let text = CStr::from_ptr(buf.as_ptr()).to_string_lossy().to_ascii_lowercase();
                        if text == want || (n == 1 && found.is_none()) {
                            found = Some(d);
                        }
                    }
                }
            }
            match found {
                Some(device) => Some(Nvml { _lib: lib, shutdown, power, device }),
                None => {
                    shutdown();
                    None
                }
            }
        }
    }

    /// Board power draw in watts.
    pub fn watts(&self) -> Option<f64> {
        let mut mw = 0;
        // SAFETY: valid device handle and out pointer.
        (unsafe { (self.power)(self.device, &mut mw) } == 0).then(|| mw as f64 / 1000.0)
    }
}

impl Drop for Nvml {
    fn drop(&mut self) {
        // SAFETY: matched with the nvmlInit_v2 in open().
        unsafe { (self.shutdown)() };
    }
}

/// Samples power every 20 ms on a thread until stopped; the mean of the samples.
pub(crate) struct PowerSampler {
    stop: Arc<AtomicBool>,
    thread: std::thread::JoinHandle<Vec<f64>>,
}

impl PowerSampler {
    pub fn start(nvml: Arc<Nvml>) -> PowerSampler {
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut samples = vec![];
            while !s.load(Ordering::Relaxed) {
                samples.extend(nvml.watts());
                std::thread::sleep(Duration::from_millis(20));
            }
            samples
        });
        PowerSampler { stop, thread }
    }

    pub fn finish(self) -> Option<f64> {
        self.stop.store(true, Ordering::Relaxed);
        let samples = self.thread.join().ok()?;
        (!samples.is_empty()).then(|| samples.iter().sum::<f64>() / samples.len() as f64)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn uuid_text_matches_nvml_format() {
        let u: [u8; 16] = std::array::from_fn(|i| (i * 17) as u8);
        assert_eq!(super::uuid_text(&u), "GPU-00112233-4455-6677-8899-aabbccddeeff");
    }
}
