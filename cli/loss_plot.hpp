// loss_plot.hpp — a small raster plotter for `ivr reconstruct`'s PREFIX_loss.png: a loss curve on
// a log-scale y axis, drawn into an ivr::Image so that save_image_file writes it (no text).
#pragma once
#include <vector>

#include "ivr/render.hpp"

namespace ivr::cli {

struct LossCurve {
  std::vector<double> iterations, losses;  // one point each; a loss <= 0 or NaN leaves a gap
  std::vector<double> markers;             // iterations drawn as vertical lines (level changes)
};

// A width x height RGBA image (alpha 1; linear values, which the PNG writer sRGB-encodes): white
// background, axes, light grid lines at every power of ten, tick marks at round iteration
// counts, the curve in a strong blue and the markers as dashed orange lines.
Image plot_loss(const LossCurve& curve, int width = 640, int height = 400);

}  // namespace ivr::cli
