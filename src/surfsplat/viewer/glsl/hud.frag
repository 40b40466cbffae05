// Text panel of the heads-up display: premultiplied RGBA, blended with (ONE, ONE_MINUS_SRC_ALPHA).
uniform sampler2D u_text;
in vec2 v_uv;
out vec4 out_color;

void main() {
    out_color = texture(u_text, v_uv);
}
