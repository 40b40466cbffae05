// Per-instance splat attributes (one instance = one splat) and the quad corner. In the compute
// visibility pass (visibility.comp, COMPUTE_SPLATS) they are plain globals it reads from the buffers.
#ifdef COMPUTE_SPLATS
#define SPLAT_IN
#else
#define SPLAT_IN in
#endif
SPLAT_IN vec2 in_corner;      // (-1,-1) .. (1,1): which corner of the bounding quad
SPLAT_IN vec3 in_position;    // model space
SPLAT_IN vec3 in_normal;      // unit center (shading) normal; the plane is spanned by u and v
SPLAT_IN vec3 in_color;       // linear RGB albedo
SPLAT_IN vec3 in_u;           // scaled tangent axis
SPLAT_IN vec3 in_v;           // scaled tangent axis, orthogonal to in_u
SPLAT_IN vec3 in_clip0;       // clip lines (a, b, c) in normalized (s, t): kept where a s + b t + c >= 0;
SPLAT_IN vec3 in_clip1;       // unbound (no clip lines) they read (0, 0, 0): nothing is clipped
SPLAT_IN vec2 in_normal_field; // (alpha, beta) of the linear normal field (Botsch 2004, eq. 2); unbound: (0, 0)
#ifdef HYBRID_POINTS
// Hybrid LiDAR drawing in the browser viewer (rendering/hybrid.py): 1 where the splat is non-planar and
// drawn as a round point facing the eye (splat_vertex.glsl, facing_axes); unbound: 0, a surface splat.
SPLAT_IN float in_nonplanar;
#endif
#ifdef SEQUENTIAL_LOD
// Sequential point trees (Dachsbacher, Vogelgsang & Stamminger 2003, sec. 3.2; hierarchy/sequential.py):
// the hierarchy's nodes and points are one list, each entry drawn only at the eye distances of its
// interval, so that a frame's LOD cut costs one uniform (render/sequential.py). Requires camera.glsl.
SPLAT_IN vec4 in_lod;              // (R, D, A, B), model units: drawn when R + max(near, s D) <= d < A + max(near, s B)
uniform float u_lod_scale;   // s = focal_px / tolerance_px

// Pixels the drawn footprint may reach beyond the splat's projected bounding sphere: the EWA prefilter
// (sqrt(2 c) for the largest cutoff c = 80, options.MAX_KERNEL_EXPONENT), pixel rounding, point sizes.
const float LOD_FRUSTUM_MARGIN_PX = 16.0;

// True when the entry at camera-space position p is outside its interval (not part of this frame's
// cut), or its bounding sphere lies entirely beyond a side plane of the tile's frustum (widened by
// LOD_FRUSTUM_MARGIN_PX): per-entry frustum culling before any other vertex work.
bool lod_rejected(vec3 p) {
    float d = length(p);   // the view is rigid: the eye distance
    float lo = in_lod.x + max(u_near_far.x, u_lod_scale * in_lod.y);
    float hi = in_lod.z + max(u_near_far.x, u_lod_scale * in_lod.w);
    if (!(d >= lo && d < hi)) return true;
    // side planes through the eye: pixel x >= x0 <=> f p.x + (x0 - cx) p.z >= 0 for p in front
    float r = max(length(in_u), length(in_v));
    vec2 c = 0.5 * u_viewport;
    vec2 a = tile_lo() - LOD_FRUSTUM_MARGIN_PX - c;
    vec2 b = tile_hi() + LOD_FRUSTUM_MARGIN_PX - c;
    vec4 side = vec4(u_focal * p.x + a.x * p.z, -u_focal * p.x - b.x * p.z,
                     u_focal * p.y + a.y * p.z, -u_focal * p.y - b.y * p.z);
    vec4 norm = sqrt(u_focal * u_focal + vec4(a.x * a.x, b.x * b.x, a.y * a.y, b.y * b.y));
    return any(lessThan(side, -r * norm));
}
#endif
