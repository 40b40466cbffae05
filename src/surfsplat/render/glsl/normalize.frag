// Third pass: per-pixel normalization by the accumulated weight (Guennebaud 2003, eq. 18).
uniform sampler2D u_accum;     // (sum w rgb, sum w)
uniform vec3 u_background;
out vec4 out_color;

void main() {
    vec4 a = texelFetch(u_accum, ivec2(gl_FragCoord.xy), 0);
    out_color = a.w > 0.0 ? vec4(clamp(a.rgb / a.w, 0.0, 1.0), 1.0) : vec4(u_background, 0.0);
}
