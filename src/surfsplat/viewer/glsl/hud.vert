// A screen-aligned rectangle (triangle strip of 4 vertices from gl_VertexID) placed in pixels.
uniform vec4 u_rect;      // x0, y0, x1, y1 in framebuffer pixels, y up
uniform vec2 u_viewport;  // framebuffer size in pixels
out vec2 v_uv;

void main() {
    vec2 corner = vec2(gl_VertexID & 1, gl_VertexID >> 1);
    v_uv = corner;  // the texture's rows are uploaded bottom first
    vec2 p = mix(u_rect.xy, u_rect.zw, corner);
    gl_Position = vec4(p / u_viewport * 2.0 - 1.0, 0.0, 1.0);
}
