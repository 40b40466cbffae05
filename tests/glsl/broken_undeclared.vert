// A vertex shader whose line 8 names an undeclared variable (tests/test_shaders.py).
#include "camera.glsl"
#include "lighting.glsl"

in vec3 in_position;

void main() {
    gl_Position = vec4(in_position * not_declared, 1.0);
}
