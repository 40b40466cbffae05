// The accumulation pass's occlusion test of a whole splat in its vertex shader (HIZ_BLOCK defined):
// u_hiz holds the farthest visible depth of each HIZ_BLOCK x HIZ_BLOCK block of the tile (hiz.frag).
// A splat none of whose depths (at least zmin) is in front of that depth in the blocks its window box
// touches has every fragment discarded by the per-fragment test (behind_nearest, splat_fragment.glsl):
// it is not drawn (no binning, no fragments). Requires camera.glsl.

#ifdef HIZ_BLOCK
uniform sampler2D u_hiz;

// Relative margin on the splat's nearest depth: the fragment shader's depth of a disk point rounds
// differently from the vertex shader's bound (the per-fragment test keeps 1e-6).
const float HIZ_SLACK = 1e-5;

// Whether the splat, whose fragments' depths are at least zmin (camera space) and whose window box is
// [lo, hi] (full-image pixels; pixel i is drawn where lo <= i + 0.5 <= hi), is hidden wherever it is
// drawn. Boxes spanning more than 2 x 2 blocks are not tested (kept).
bool hidden_splat(vec2 lo, vec2 hi, float zmin) {
    ivec2 last_block = textureSize(u_hiz, 0) - 1;
    ivec2 a = clamp(ivec2(floor((ceil(lo - 0.5) - u_tile.xy) / float(HIZ_BLOCK))), ivec2(0), last_block);
    ivec2 b = clamp(ivec2(floor((floor(hi - 0.5) - u_tile.xy) / float(HIZ_BLOCK))), ivec2(0), last_block);
    if (any(greaterThan(b - a, ivec2(1)))) return false;
    float far = max(max(texelFetch(u_hiz, a, 0).r, texelFetch(u_hiz, ivec2(b.x, a.y), 0).r),
                    max(texelFetch(u_hiz, ivec2(a.x, b.y), 0).r, texelFetch(u_hiz, b, 0).r));
    return zmin * (1.0 - HIZ_SLACK) > far * (1.0 + HIZ_SLACK);
}
#endif
