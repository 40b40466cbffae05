// Third pass: per-pixel normalization by the accumulated weight (Guennebaud 2003,
// eq. 18; Pajarola 2003, EQ 9), and deferred shading of the blended normals
// (Zwicker et al. 2001; Botsch 2004, fig. 7) when the splats carried their albedo.
#include "camera.glsl"
#include "lighting.glsl"

uniform sampler2D u_accum;     // (sum w rgb, sum w)
uniform sampler2D u_aux;       // (sum w depth, sum w normal), camera space
uniform vec3 u_background;
uniform bool u_deferred;
out vec4 out_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 a = texelFetch(u_accum, px, 0);
    if (!(a.w > 0.0)) { out_color = vec4(u_background, 0.0); return; }
    vec3 color = a.rgb / a.w;
    if (u_deferred) {
        vec3 n = texelFetch(u_aux, px, 0).yzw;
        if (dot(n, n) > 0.0) color = shade(color, normalize(n), normalize(-pixel_ray(FRAG_PX)));
    }
    // last resort: a non-finite accumulation (a degenerate splat) shows the background, never NaN;
    // the renderer counts these pixels from the targets and warns (Renderer.render)
    if (any(isnan(a)) || any(isinf(a)) || any(isnan(color)) || any(isinf(color))) {
        out_color = vec4(u_background, 0.0);
        return;
    }
    out_color = vec4(clamp(color, 0.0, 1.0), 1.0);
}
