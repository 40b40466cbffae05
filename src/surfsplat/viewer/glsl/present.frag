// Shows the rendered image in the window: the motion preview cross-faded into the
// full-quality frame (both rendered off-screen by the Renderer; see viewer/app.py).
uniform sampler2D u_preview;  // last motion-preview frame, possibly at a lower resolution (bilinear upscaling)
uniform sampler2D u_full;     // last full-quality frame, framebuffer size
uniform float u_mix;          // 0: preview only, 1: full quality only
uniform vec2 u_viewport;      // framebuffer size in pixels
out vec4 out_color;

void main() {
    vec2 uv = gl_FragCoord.xy / u_viewport;  // pixel centers: exact texels at full size
    vec3 color = mix(texture(u_preview, uv).rgb, texture(u_full, uv).rgb, u_mix);
    out_color = vec4(color, 1.0);
}
