// The one place that includes the OpenGL headers. GL 4.5 core entry points are
// exported by libOpenGL (glvnd), so prototypes are enough: no loader needed.
#pragma once

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>
