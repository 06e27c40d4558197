//! The few 3-vector helpers the renderer needs.

pub use tetloc_core::Vec3;

#[inline(always)]
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline(always)]
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
pub fn scale(a: Vec3, s: f32) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline(always)]
pub fn dot(a: Vec3, b: Vec3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
#[inline(always)]
pub fn len(a: Vec3) -> f32 {
    dot(a, a).sqrt()
}
/// `a / |a|`, or `None` for a (near) zero vector.
#[inline]
pub fn normalize(a: Vec3) -> Option<Vec3> {
    let l = len(a);
    (l > 1e-20 && l.is_finite()).then(|| scale(a, 1.0 / l))
}
/// `o + t·d`: one formula for every sample position, so both marching modes get identical points.
#[inline(always)]
pub fn at(o: Vec3, d: Vec3, t: f32) -> Vec3 {
    [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]]
}
