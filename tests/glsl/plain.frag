// A valid fragment shader to pair with the broken ones (tests/test_shaders.py).
uniform vec3 u_tint;
out vec4 out_color;

void main() {
    out_color = vec4(u_tint, 1.0);
}
