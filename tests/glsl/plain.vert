// A valid vertex shader to pair with the broken ones (tests/test_shaders.py).
in vec3 in_position;

void main() {
    gl_Position = vec4(in_position, 1.0);
}
