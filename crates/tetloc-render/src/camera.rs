//! A perspective pinhole camera: fitted around the mesh bounds from an azimuth/elevation
//! view, or placed explicitly by eye, target and up.

use crate::vec::{add, cross, len, normalize, scale, sub, Vec3};

/// Vertical field of view of every camera before zoom, in degrees.
pub const FOV_Y_DEG: f32 = 30.0;

/// An explicit camera placement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookAt {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
}

impl LookAt {
    /// Whether a camera can be placed so: eye and target apart, and `up` far enough from the
    /// view direction (sine of the angle ≥ 1e-4) that turning the eye about `up` for an
    /// orbit, with its rounding, keeps it so.
    pub fn is_usable(&self) -> bool {
        match (normalize(sub(self.target, self.eye)), normalize(self.up)) {
            (Some(f), Some(u)) => len(cross(f, u)) >= 1e-4,
            _ => false,
        }
    }
}

/// A ray with a unit direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    /// tan(fov_y / 2) after zoom.
    tan_half_y: f32,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    /// A camera at `look.eye` looking at `look.target`. Returns `None` when eye and target
    /// coincide or `up` is parallel to the view direction.
    pub fn look_at(look: LookAt, zoom: f32, width: u32, height: u32) -> Option<Camera> {
        let forward = normalize(sub(look.target, look.eye))?;
        let c = cross(forward, normalize(look.up)?);
        // Nearly parallel up and view directions give no usable image plane.
        if len(c) < 1e-6 {
            return None;
        }
        let right = normalize(c)?;
        let up = cross(right, forward);
        let tan_half_y = (0.5 * FOV_Y_DEG.to_radians()).tan() / zoom;
        Some(Camera { eye: look.eye, forward, right, up, tan_half_y, width, height })
    }

    /// A camera around the box `[lo, hi]`: looking at its centre from azimuth `az` and
    /// elevation `el` (degrees; +z is up, azimuth 0 looks along +y, 90 along −x), far enough
    /// that the box's bounding sphere fills the narrower image axis at zoom 1.
    pub fn fitted(lo: Vec3, hi: Vec3, az: f32, el: f32, zoom: f32, width: u32, height: u32) -> Camera {
        let center = scale(add(lo, hi), 0.5);
        let radius = match 0.5 * len(sub(hi, lo)) {
            r if r > 0.0 => r,
            _ => 1.0, // a point-like mesh: any distance shows it
        };
        let (az, el) = (az.to_radians(), el.to_radians());
        let toward_eye = [el.cos() * az.sin(), -el.cos() * az.cos(), el.sin()];
        let tan_y = (0.5 * FOV_Y_DEG.to_radians()).tan();
        let aspect = width as f32 / height.max(1) as f32;
        let half_fov_min = tan_y.min(tan_y * aspect).atan();
        let dist = radius / half_fov_min.sin();
        let eye = add(center, scale(toward_eye, dist));
        // Straight up or down: +y stands in for up.
        let up = if el.cos().abs() < 1e-4 { [0.0, 1.0, 0.0] } else { [0.0, 0.0, 1.0] };
        Camera::look_at(LookAt { eye, target: center, up }, zoom, width, height)
            .expect("fitted camera is non-degenerate")
    }

    /// The ray through the centre of pixel (x, y), y = 0 at the top.
    pub fn ray(&self, x: u32, y: u32) -> Ray {
        let aspect = self.width as f32 / self.height as f32;
        let u = ((x as f32 + 0.5) / self.width as f32 * 2.0 - 1.0) * self.tan_half_y * aspect;
        let v = (1.0 - (y as f32 + 0.5) / self.height as f32 * 2.0) * self.tan_half_y;
        let d = add(self.forward, add(scale(self.right, u), scale(self.up, v)));
        Ray { origin: self.eye, dir: normalize(d).unwrap_or(self.forward) }
    }

    /// All rays of the image in row-major order.
    pub fn rays(&self) -> Vec<Ray> {
        (0..self.height).flat_map(|y| (0..self.width).map(move |x| self.ray(x, y))).collect()
    }

    pub fn forward(&self) -> Vec3 {
        self.forward
    }
    pub fn right(&self) -> Vec3 {
        self.right
    }
    pub fn up(&self) -> Vec3 {
        self.up
    }
    /// tan(fov_y / 2) after zoom.
    pub fn tan_half_y(&self) -> f32 {
        self.tan_half_y
    }
}

/// The parametric interval `[t_near, t_far]` where `ray` is inside the box, clipped to
/// `t ≥ 0`; `None` when it misses.
pub fn clip_to_box(ray: &Ray, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
    let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
    for k in 0..3 {
        let inv = 1.0 / ray.dir[k];
        let (a, b) = ((lo[k] - ray.origin[k]) * inv, (hi[k] - ray.origin[k]) * inv);
        // A ray parallel to a slab gives ±inf (or NaN on its plane); min/max skip NaN.
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1).then_some((t0, t1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vec::dot;

    /// Whether `point` is in front of the camera.
    fn faces(cam: &Camera, point: Vec3) -> bool {
        dot(cam.forward, sub(point, cam.eye)) > 0.0
    }

    #[test]
    fn fitted_camera_sees_the_whole_box() {
        let (lo, hi) = ([-1.0, 0.0, 2.0], [3.0, 1.0, 4.0]);
        for (az, el, w, h) in [(0.0, 0.0, 64, 64), (30.0, 20.0, 200, 100), (-120.0, 70.0, 50, 120), (0.0, 90.0, 40, 40)]
        {
            let cam = Camera::fitted(lo, hi, az, el, 1.0, w, h);
            // Every box corner projects inside the image.
            for i in 0..8 {
                let c = [
                    if i & 1 == 0 { lo[0] } else { hi[0] },
                    if i & 2 == 0 { lo[1] } else { hi[1] },
                    if i & 4 == 0 { lo[2] } else { hi[2] },
                ];
                assert!(faces(&cam, c));
                let d = sub(c, cam.eye);
                let z = dot(d, cam.forward);
                let (u, v) = (dot(d, cam.right) / z, dot(d, cam.up) / z);
                let aspect = w as f32 / h as f32;
                assert!(
                    u.abs() <= cam.tan_half_y * aspect && v.abs() <= cam.tan_half_y,
                    "{az},{el}: corner {c:?} off screen"
                );
            }
        }
    }

    #[test]
    fn azimuth_zero_looks_along_y_and_zoom_narrows() {
        let cam = Camera::fitted([0.0; 3], [1.0; 3], 0.0, 0.0, 1.0, 9, 9);
        let f = cam.forward();
        assert!((f[1] - 1.0).abs() < 1e-6, "{f:?}");
        let centre = cam.ray(4, 4);
        assert!((centre.dir[1] - 1.0).abs() < 1e-6);
        let zoomed = Camera::fitted([0.0; 3], [1.0; 3], 0.0, 0.0, 2.0, 9, 9);
        assert!(zoomed.ray(0, 0).dir[1] > cam.ray(0, 0).dir[1], "corner rays move inward");
        assert_eq!(zoomed.eye, cam.eye, "zoom does not move the eye into the volume");
        // Pixel (0, 0) is top left: up and to the left.
        let tl = cam.ray(0, 0).dir;
        assert!(tl[2] > 0.0 && tl[0] < 0.0, "{tl:?}");
    }

    #[test]
    fn look_at_rejects_degenerate_placements() {
        assert!(Camera::look_at(LookAt { eye: [1.0; 3], target: [1.0; 3], up: [0.0, 0.0, 1.0] }, 1.0, 4, 4).is_none());
        assert!(Camera::look_at(LookAt { eye: [0.0; 3], target: [0.0, 0.0, 5.0], up: [0.0, 0.0, 1.0] }, 1.0, 4, 4)
            .is_none());
    }

    #[test]
    fn nearly_parallel_up_is_not_usable() {
        let look = |up: Vec3| LookAt { eye: [0.0, 0.0, 5.0], target: [0.0; 3], up };
        assert!(look([0.0, 1.0, 0.0]).is_usable());
        assert!(!look([0.0, 1e-6, 1.0]).is_usable());
        assert!(!look([0.0; 3]).is_usable());
        assert!(!LookAt { eye: [1.0; 3], target: [1.0; 3], up: [0.0, 0.0, 1.0] }.is_usable());
    }

    #[test]
    fn box_clipping() {
        let r = Ray { origin: [-1.0, 0.5, 0.5], dir: [1.0, 0.0, 0.0] };
        assert_eq!(clip_to_box(&r, [0.0; 3], [1.0; 3]), Some((1.0, 2.0)));
        let inside = Ray { origin: [0.5; 3], dir: [0.0, 0.0, -1.0] };
        assert_eq!(clip_to_box(&inside, [0.0; 3], [1.0; 3]), Some((0.0, 0.5)));
        let miss = Ray { origin: [-1.0, 2.0, 0.5], dir: [1.0, 0.0, 0.0] };
        assert_eq!(clip_to_box(&miss, [0.0; 3], [1.0; 3]), None);
        let behind = Ray { origin: [2.0, 0.5, 0.5], dir: [1.0, 0.0, 0.0] };
        assert_eq!(clip_to_box(&behind, [0.0; 3], [1.0; 3]), None);
    }
}
