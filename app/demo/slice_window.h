// The demo's density-lighting slice: a cross-section of the radiance S (paper Fig. 6(b,d)),
// the x-z slice through its brightest cell (where the bolt lights the cloud), in its own
// ImGui window at the bottom right of the demo window.
#pragma once

#include "runtime/runtime.h"

#include <memory>

namespace fulgur::app {

class SliceWindow {
public:
    /// Needs the demo window's GL context current: loads the few GL calls of the slice image
    /// through the window's get-proc-address (the process also links OSMesa, whose gl*
    /// symbols must not be called on a GLX context) and makes the slice's texture.
    SliceWindow();
    ~SliceWindow();
    SliceWindow(const SliceWindow&) = delete;
    SliceWindow& operator=(const SliceWindow&) = delete;

    /// Uploads the slice of frame f (nothing when f is null, dark or has no radiance) and
    /// draws its window; width x height: the demo window's size in pixels.
    void draw(const runtime::Frame* f, int width, int height);

private:
    struct Gl;
    std::unique_ptr<const Gl> gl_;
    unsigned texture_ = 0;
};

}  // namespace fulgur::app
