#pragma once
// OpenGL 3.3 core entry points. On Linux, libGL (glvnd / Mesa) exports every core function,
// so the prototypes of glcorearb.h are linked directly (no loader library needed).
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
