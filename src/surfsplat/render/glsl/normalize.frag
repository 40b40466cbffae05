// Third pass: per-pixel normalization by the accumulated weight (Guennebaud 2003,
// eq. 18; Pajarola 2003, EQ 9), and deferred shading of the blended normals
// (Zwicker et al. 2001; Botsch 2004, fig. 7) when the splats carried their albedo.
#include "camera.glsl"
#include "lighting.glsl"

uniform sampler2D u_accum;     // (sum w rgb, sum w)
uniform sampler2D u_aux;       // (sum w depth, sum w normal), camera space
uniform vec3 u_background;
uniform bool u_deferred;
// What Renderer.render reads back (20 bytes per sub-pixel): the color and the accumulated weight
// (-1: a non-finite accumulation), and the weighted depth sum (the depth is it over the weight).
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_depth;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 a = texelFetch(u_accum, px, 0);
    vec4 aux = texelFetch(u_aux, px, 0);
    out_depth = 0.0;
    // last resort: a non-finite accumulation (a degenerate splat) shows the background, never NaN;
    // the renderer counts these pixels (weight -1) and warns (Renderer.render)
    bool finite = !(any(isnan(a)) || any(isinf(a)) || any(isnan(aux)) || any(isinf(aux)));
    if (finite && !(a.w > 0.0)) { out_color = vec4(u_background, 0.0); return; }
    vec3 color = a.rgb / a.w;
    if (finite && u_deferred) {
        vec3 n = aux.yzw;
        if (dot(n, n) > 0.0) color = shade(color, normalize(n), normalize(-pixel_ray(FRAG_PX)));
    }
    if (!finite || any(isnan(color)) || any(isinf(color))) {
        out_color = vec4(u_background, -1.0);
        return;
    }
    out_color = vec4(clamp(color, 0.0, 1.0), a.w);
    out_depth = aux.x;
}
