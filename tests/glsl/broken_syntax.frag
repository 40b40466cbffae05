// A fragment shader with a syntax error on line 6 (tests/test_shaders.py).
#include "camera.glsl"
out vec4 out_color;

void main() {
    out_color = vec4(1.0) +;
}
