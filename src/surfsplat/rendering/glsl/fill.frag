// After the normalization pass: screen-space hole filling (surfsplat.reference.fill_holes is the rule
// in NumPy; the two are held against each other by tests/test_fill_holes.py). A pixel is a hole when
// no splat covers it or the splats covering it lie behind the surface around it; it is filled when the
// surface around it encloses it: along at least 3 of the 4 axes (horizontal, vertical, both diagonals)
// the nearest pixels on both sides that lie in front of it (any covered pixel, for an uncovered one)
// leave a gap of at most u_fill_gap pixels between them (their distances add up to at most u_fill_gap + 1). It takes the
// depth, color, weight and coverage of the front surface among those neighbours (those within the
// depth tolerance of the nearest), each weighted by the inverse of its distance along its axis. A hole
// in a surface is enclosed; the background beyond a silhouette (convex or concave: a corner encloses
// it along one axis) is not, so silhouettes never grow; a larger hole is not. The screen-space rule of
// Pintus et al. 2011 (enclosure along the 4 axes, front neighbours only) with the bounded gap of
// Marroquim et al. 2007, searched directly: the gaps are a few pixels, where a pull-push pyramid
// (Grossman & Dally 1998) would fill holes of any size.
#include "camera.glsl"

uniform sampler2D u_norm_color;   // normalize.frag's color (mixed over the background) and weight
uniform sampler2D u_norm_depth;   // normalize.frag's weighted depth sum and coverage alpha
uniform int u_fill_gap;           // pixels: the widest gap filled (0: off)
uniform float u_fill_depth;       // depth tolerance in pixels: tau(z) = u_fill_depth * z / u_focal

layout(location = 0) out vec4 out_color;
layout(location = 1) out vec2 out_depth;

const float FAR = 1e30;   // the depth of an uncovered pixel

// The color and weight, the depth sum and alpha, and the depth (FAR where uncovered) at an offset;
// false outside the full image (tiles are drawn with a margin: a neighbour inside it is in the tile).
bool pixel_at(ivec2 offset, out vec4 color, out vec2 depth_alpha, out float z) {
    vec2 px = FRAG_PX + vec2(offset);
    if (any(lessThan(px, vec2(0.0))) || any(greaterThanEqual(px, u_viewport))) return false;
    ivec2 texel = clamp(ivec2(gl_FragCoord.xy) + offset, ivec2(0), textureSize(u_norm_color, 0) - 1);
    color = texelFetch(u_norm_color, texel, 0);
    depth_alpha = texelFetch(u_norm_depth, texel, 0).rg;
    z = color.a > 0.0 ? depth_alpha.x / color.a : FAR;
    return true;
}

// The depth tolerance at depth z: the surfaces of two pixels are apart when their depths differ by more.
float tolerance(float z) {
    return u_fill_depth * z / u_focal;
}

void main() {
    vec4 color;
    vec2 depth_alpha;
    float z;
    pixel_at(ivec2(0), color, depth_alpha, z);
    out_color = color;
    out_depth = depth_alpha;
    if (u_fill_gap <= 0 || color.a < 0.0) return;   // off, or a non-finite accumulation (counted)
    float limit = z < FAR ? z - tolerance(z) : FAR;   // a neighbour in front: nearer than this
    const ivec2 AXES[4] = ivec2[4](ivec2(1, 0), ivec2(0, 1), ivec2(1, 1), ivec2(1, -1));
    // per axis and side: the distance of the nearest pixel in front (0: none) and its values
    int steps[8];
    vec4 colors[8];
    vec2 depths[8];
    float zs[8];
    int enclosed = 0;
    for (int i = 0; i < 8; ++i) {
        ivec2 dir = AXES[i / 2] * (i % 2 == 0 ? 1 : -1);
        steps[i] = 0;
        for (int k = 1; k <= u_fill_gap; ++k) {
            vec4 c;
            vec2 da;
            float zq;
            if (!pixel_at(dir * k, c, da, zq)) break;
            if (zq < limit) {
                steps[i] = k;
                colors[i] = c;
                depths[i] = da;
                zs[i] = zq;
                break;
            }
        }
    }
    bool axis[4];
    for (int a = 0; a < 4; ++a) {
        axis[a] = steps[2 * a] > 0 && steps[2 * a + 1] > 0 && steps[2 * a] + steps[2 * a + 1] <= u_fill_gap + 1;
        enclosed += int(axis[a]);
    }
    if (enclosed < 3) return;
    float front = FAR;
    for (int i = 0; i < 8; ++i)
        if (axis[i / 2]) front = min(front, zs[i]);
    float keep = front + tolerance(front);
    vec4 sum_color = vec4(0.0);
    vec3 sum_depth = vec3(0.0);   // depth, alpha, weight of the inverse distances
    for (int i = 0; i < 8; ++i) {
        if (!axis[i / 2] || zs[i] > keep) continue;
        float w = 1.0 / float(steps[i]);
        sum_color += w * colors[i];
        sum_depth += w * vec3(zs[i], depths[i].y, 1.0);
    }
    vec4 filled = sum_color / sum_depth.z;
    out_color = filled;
    out_depth = vec2(sum_depth.x / sum_depth.z * filled.a, sum_depth.y / sum_depth.z);
}
