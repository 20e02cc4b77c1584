// loss_plot.hpp — `ivr reconstruct`'s PREFIX_loss.svg: the loss per iteration, an SVG plot.
#pragma once
#include <string>
#include <vector>

namespace ivr::cli {

// A coarse-to-fine level: its first iteration and a name for it ("16³"). The first level is
// named at the plot's left; every later one is also drawn as a dashed vertical line.
struct LevelStart {
  double iteration = 0;
  std::string name;
};

struct LossCurve {
  std::vector<double> iterations, losses;  // one point each; a loss <= 0 or not finite: a gap
  std::vector<double> priors;              // empty, or one per point: drawn where any is > 0
  std::vector<LevelStart> levels;
  std::string loss_name = "MSE";          // the y axis reads "loss (MSE)"
  std::string loss_label = "image loss";  // the legend's name of the loss curve
  std::string title;
};

// The plot as a standalone SVG document (UTF-8; text in a sans-serif font). The y axis is
// logarithmic over whole decades around every drawable value, labelled at each decade (and at 2
// and 5 times them when the range spans two decades or less); the x axis has round iteration
// counts. The legend sits right of the plot area, so no curve can hide it. Escapes every string.
std::string loss_svg(const LossCurve& curve, int width = 800, int height = 450);

}  // namespace ivr::cli
