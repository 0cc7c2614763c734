// parallax view: a GLFW window showing both eyes side by side as the stereo pipeline finishes
// them, with a fly-through camera. Only the parallax executable compiles this (GLFW and OpenGL
// stay out of parallax_core); run_view itself is declared in app/commands.h.
//
// Threads: the render thread owns the OpenCL side (pipeline, control loop) and renders frame
// after frame; after each it hands the finished RGBA8 eyes over under a mutex (a vector swap).
// The main thread owns the window: it polls input, publishes the steered camera, and uploads
// the newest frame through a pixel buffer object. Neither waits for the other: the window never
// blocks the render queues, and a slow frame never freezes the window.
#pragma once

#include "app/commands.h"
