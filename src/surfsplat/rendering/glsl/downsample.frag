// Supersampling in the browser viewer: the K x K sub-pixels of each output pixel reduced to one, as
// rendering/tiles.py box_reduce reduces the desktop renderer's sub-pixels (its NumPy twin): the colour
// is their mean (each sub-pixel's colour is already over the background where uncovered), the alpha the
// mean coverage and the depth the nearest covered sub-pixel's. The output keeps the layout of
// normalize.frag's, which edl.frag reads: (rgb, weight) with weight 1 where a sub-pixel is covered, else 0,
// and (depth times that weight, alpha).

uniform sampler2D u_sub_color;   // normalize.frag's (or fill.frag's) out_color: (rgb over the background, weight)
uniform sampler2D u_sub_depth;   // their out_depth: (weighted depth sum, coverage alpha)
uniform int u_factor;            // K: sub-pixels per output pixel along each axis

layout(location = 0) out vec4 out_color;
layout(location = 1) out vec2 out_depth;

void main() {
    ivec2 base = ivec2(gl_FragCoord.xy) * u_factor;
    vec3 sum = vec3(0.0);
    float alpha = 0.0;
    float nearest = FILL_FAR;
    for (int y = 0; y < u_factor; ++y) {
        for (int x = 0; x < u_factor; ++x) {
            ivec2 texel = base + ivec2(x, y);
            vec4 c = texelFetch(u_sub_color, texel, 0);
            vec2 d = texelFetch(u_sub_depth, texel, 0).rg;
            sum += c.rgb;
            alpha += d.y;
            if (c.a > 0.0) nearest = min(nearest, d.x / c.a);
        }
    }
    float n = float(u_factor * u_factor);
    float covered = nearest < FILL_FAR ? 1.0 : 0.0;
    out_color = vec4(sum / n, covered);
    out_depth = vec2(nearest * covered, alpha / n);
}
