// Eye-dome lighting (Boucheny 2009) of a normalized image, as a full-screen pass: the formula of
// rendering/edl.py (its NumPy twin, which the desktop renderer applies to the assembled Frame), for
// drawing paths that keep the image on the GPU (the browser viewer). For each covered pixel p with
// camera-space depth z_p, over the EDL_NEIGHBOURS whole-pixel offsets u_edl_offsets (edl.neighbour_offsets):
//     obscurance(p) = sum_n max(0, log2 z_p - log2 z_n),   shade(p) = exp(-u_edl_strength obscurance(p));
// neighbours outside the image or with no surface add nothing, and only the surface's share of a pixel
// (its coverage alpha) is shaded: color = bg (1 - alpha) + (color - bg (1 - alpha)) shade.

uniform sampler2D u_color;   // normalize.frag's out_color: (rgb over the background, weight; <= 0: empty)
uniform sampler2D u_depth;   // normalize.frag's out_depth: (weighted depth sum, coverage alpha)
uniform vec3 u_background;
uniform float u_edl_strength;
uniform ivec2 u_edl_offsets[EDL_NEIGHBOURS];

layout(location = 0) out vec4 out_color;

// log2 of the camera-space depth of a texel's surface; false where it has none (edl.py: inf).
bool log_depth(ivec2 texel, out float logz) {
    float weight = texelFetch(u_color, texel, 0).a;
    float z = weight > 0.0 ? texelFetch(u_depth, texel, 0).r / weight : 0.0;
    logz = z > 0.0 ? log2(z) : 0.0;
    return z > 0.0;
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    ivec2 size = textureSize(u_color, 0);
    vec4 c = texelFetch(u_color, px, 0);
    float here;
    if (!log_depth(px, here)) { out_color = vec4(c.rgb, 1.0); return; }
    float total = 0.0;
    for (int i = 0; i < EDL_NEIGHBOURS; ++i) {
        ivec2 q = px + u_edl_offsets[i];
        float there;
        if (all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, size)) && log_depth(q, there))
            total += max(0.0, here - there);
    }
    float shade = exp(-u_edl_strength * total);
    vec3 behind = u_background * (1.0 - texelFetch(u_depth, px, 0).g);
    out_color = vec4(behind + (c.rgb - behind) * shade, 1.0);
}
