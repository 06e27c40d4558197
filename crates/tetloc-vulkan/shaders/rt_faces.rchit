#version 460
// rt-rep-faces (REP_FACES) and rt-shared-faces (SHARED_FACES): the closest face hit along
// the ray names a candidate tet, which the point-in-tet test confirms (paper Fig. 5, 6).
//
// rep-faces: four inward-facing triangles per tet, back faces culled, so the closest hit is
// a face of the tet the ray starts in. shared-faces: each face once; the side the ray comes
// from is the candidate. Vulkan calls a hit front-facing when the ray travels against
// n = (v1 - v0) x (v2 - v0), i.e. it starts on the side n points to: that is the face's
// `back` tet in tetloc_core::mesh::Face's convention.
//
// When rounding puts the hit on the wrong side of a face or edge (points within rounding of
// it), the candidate fails the test; a short walk through tet neighbours then finds the
// containing tet, so no interior point falls through a crack. A walk that finds nothing
// sends the ray generation shader to try the opposite direction. A point on the boundary of
// the tet found goes to the lowest tet that holds it (walk.glsl tl_lowest_holder).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_EXT_ray_tracing : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "common/tet.glsl"
#include "common/rt.glsl"
#include "common/walk.glsl"

#ifdef REP_FACES
// Triangle 4k + j of the concatenated BLAS inputs belongs to tet tl_prim_tet[k].
layout(std430, binding = TL_B_PRIMS) readonly buffer TlPrimTet { uint tl_prim_tet[]; };
#else
// (front, back) tets of each face, -1 for none (tetloc_core::mesh::Face).
layout(std430, binding = TL_B_PRIMS) readonly buffer TlFaceTets { ivec2 tl_face_tets[]; };
#endif

layout(location = 0) rayPayloadInEXT TlPayload pl;

void main() {
    uint prim = tl_instance_base[gl_InstanceID] + gl_PrimitiveID;
#ifdef REP_FACES
    int tet = int(tl_prim_tet[prim >> 2]);
#else
    ivec2 sides = tl_face_tets[prim];
    bool from_back = gl_HitKindEXT == gl_HitKindFrontFacingTriangleEXT;
    int tet = from_back ? sides.y : sides.x;
    if (tet < 0) {
        // The ray comes from outside the mesh: confirm that with the tet behind the face.
        tet = from_back ? sides.x : sides.y;
    }
#endif
    vec3 p = gl_WorldRayOriginEXT;
    uvec4 ids;
    vec4 bary;
    tet = tl_walk(tet, p, WALK_MAX, ids, bary);
    if (tet >= 0) {
        // A point on the tet's boundary: the tie rule, through the neighbours.
        pl.tet = tl_on_boundary ? tl_lowest_holder(tet, bary, p) : tet;
        return;
    }
    // Not found: the point is outside the mesh, or the hit was a face coincident with
    // another (a seam of duplicated vertices) that led the walk astray. Report it like a
    // miss, so that the ray generation shader tries the opposite direction once.
    pl.tet = TL_MISS;
}
