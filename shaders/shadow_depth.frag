// Shadow pass: no colour attachment; the rasterizer writes gl_FragCoord.z to
// the depth texture by itself.
void main() {}
