// loss_plot_test.cpp — the CLI's SVG loss plot (cli/loss_plot.cpp): well-formed, labelled, finite.
#include "cli/loss_plot.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "reconstruct/svg_check.hpp"

namespace ivr::test {
namespace {

using cli::loss_svg;
using cli::LossCurve;

std::vector<XmlElement> with_class(const std::vector<XmlElement>& all, const std::string& cls) {
  std::vector<XmlElement> out;
  for (const XmlElement& e : all)
    if (e.attributes.count("class") && e.attributes.at("class") == cls) out.push_back(e);
  return out;
}

std::vector<double> tick_values(const std::vector<XmlElement>& all) {
  std::vector<double> out;
  for (const XmlElement& e : with_class(all, "y-tick")) out.push_back(tick_value(e.text));
  return out;
}

// No coordinate or size of any element is NaN or infinite (the writer's "%.2f" would print
// "nan"/"inf"), and every number in a points list parses.
void expect_finite_attributes(const std::vector<XmlElement>& all) {
  for (const XmlElement& e : all)
    for (const auto& [name, value] : e.attributes) {
      if (name == "font-family" || name == "class" || name == "xmlns") continue;
      std::string lower = value;
      std::transform(lower.begin(), lower.end(), lower.begin(), ::tolower);
      EXPECT_EQ(lower.find("nan"), std::string::npos) << e.name << " " << name << "=" << value;
      EXPECT_EQ(lower.find("inf"), std::string::npos) << e.name << " " << name << "=" << value;
    }
}

void expect_ticks(const std::vector<double>& got, const std::vector<double>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_NEAR(got[i], want[i], 1e-12 * want[i]) << i;
}

std::size_t points_in(const XmlElement& polyline) {
  const std::string& p = polyline.attributes.at("points");
  return std::size_t(std::count(p.begin(), p.end(), ','));
}

// 200 iterations of a loss falling from 3e-2 to about 2e-4 over three levels, a prior beside it.
LossCurve falling() {
  LossCurve c;
  for (int k = 1; k <= 200; ++k) {
    c.iterations.push_back(k);
    c.losses.push_back(0.03 * std::exp(-k / 40.0));
    c.priors.push_back(0.0);
  }
  c.levels = {{1, "8³"}, {25, "16³"}, {80, "32×32×16"}};
  c.title = "ivr reconstruct: density, adam lr 0.025, 200 iterations";
  return c;
}

TEST(LossSvg, HasAxisTitlesNumberedTicksCoveringTheLossesALegendAndATitle) {
  const LossCurve c = falling();
  const std::string svg = loss_svg(c);
  const std::vector<XmlElement> all = parse_xml(svg);
  ASSERT_EQ(all.front().name, "svg");
  EXPECT_EQ(all.front().attributes.at("xmlns"), "http://www.w3.org/2000/svg");
  expect_finite_attributes(all);

  ASSERT_EQ(with_class(all, "x-title").size(), 1u);
  EXPECT_EQ(with_class(all, "x-title")[0].text, "iteration");
  ASSERT_EQ(with_class(all, "y-title").size(), 1u);
  EXPECT_EQ(with_class(all, "y-title")[0].text, "loss (MSE, log scale)");
  ASSERT_EQ(with_class(all, "title").size(), 1u);
  EXPECT_EQ(with_class(all, "title")[0].text, c.title);

  // y: the decades 10⁻⁴ .. 10⁻¹ around [2.0e-4, 2.9e-2], each labelled, in order.
  const std::vector<double> y = tick_values(all);
  expect_ticks(y, {1e-4, 1e-3, 1e-2, 1e-1});
  const double lo = *std::min_element(c.losses.begin(), c.losses.end());
  const double hi = *std::max_element(c.losses.begin(), c.losses.end());
  EXPECT_LE(y.front(), lo);
  EXPECT_GT(y.front() * 10, lo);
  EXPECT_GE(y.back(), hi);
  EXPECT_LT(y.back(), hi * 10);
  // x: round steps from 0 to the last iteration.
  std::vector<std::string> x;
  for (const XmlElement& e : with_class(all, "x-tick")) x.push_back(e.text);
  EXPECT_EQ(x, (std::vector<std::string>{"0", "50", "100", "150", "200"}));

  // The curve: one polyline through every point; the priors are all 0, so not drawn.
  const std::vector<XmlElement> loss = with_class(all, "loss");
  ASSERT_EQ(loss.size(), 1u);
  EXPECT_EQ(points_in(loss[0]), 200u);
  EXPECT_TRUE(with_class(all, "prior").empty());

  // The legend names the curve and the level changes; the levels are named; the stats are right.
  std::vector<std::string> legend, levels, stats;
  for (const XmlElement& e : with_class(all, "legend")) legend.push_back(e.text);
  for (const XmlElement& e : with_class(all, "level")) levels.push_back(e.text);
  for (const XmlElement& e : with_class(all, "stat")) stats.push_back(e.text);
  EXPECT_EQ(legend, (std::vector<std::string>{"image loss (MSE)", "level change"}));
  EXPECT_EQ(levels, (std::vector<std::string>{"8³", "16³", "32×32×16"}));
  ASSERT_EQ(stats.size(), 3u);
  EXPECT_EQ(stats[0], "first 2.93×10⁻²");  // 0.03 e^(−1/40) = 0.029259
  EXPECT_EQ(stats[1], "last 2.02×10⁻⁴");   // 0.03 e^(−5) = 0.00020214
  EXPECT_EQ(stats[2], "lowest 2.02×10⁻⁴ (it. 200)");
  // Two dashed level lines (the first level starts at the axis).
  EXPECT_EQ(with_class(all, "level-change").size(), 2u);
}

TEST(LossSvg, FewDecadesAlsoLabelTwoAndFiveTimesThemAndTheL1NameReachesTheAxis) {
  LossCurve c;
  c.iterations = {1, 2, 3};
  c.losses = {0.04, 0.02, 0.011};
  c.loss_name = "L1";
  const std::vector<XmlElement> all = parse_xml(loss_svg(c));
  expect_ticks(tick_values(all), {1e-2, 2e-2, 5e-2, 1e-1});
  EXPECT_EQ(with_class(all, "y-title")[0].text, "loss (L1, log scale)");
  EXPECT_EQ(with_class(all, "legend")[0].text, "image loss (L1)");
  EXPECT_TRUE(with_class(all, "title").empty());  // none given, none drawn
}

TEST(LossSvg, GapsAtNonPositiveOrNonFiniteLossesAndALonePointAsADot) {
  const double nan = std::numeric_limits<double>::quiet_NaN(),
               inf = std::numeric_limits<double>::infinity();
  LossCurve c;
  c.iterations = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  c.losses = {1, 0.5, nan, 0.25, -1, 0.1, 0.05, inf, 0};
  const std::string svg = loss_svg(c);
  const std::vector<XmlElement> all = parse_xml(svg);
  expect_finite_attributes(all);
  // Runs: {1, 0.5}, {0.25} (a dot), {0.1, 0.05}.
  const std::vector<XmlElement> loss = with_class(all, "loss");
  ASSERT_EQ(loss.size(), 3u);
  EXPECT_EQ(loss[0].name, "polyline");
  EXPECT_EQ(points_in(loss[0]), 2u);
  EXPECT_EQ(loss[1].name, "circle");
  EXPECT_EQ(points_in(loss[2]), 2u);
  // Two decades (10⁻² .. 1): 2 and 5 times each labelled too.
  expect_ticks(tick_values(all), {1e-2, 2e-2, 5e-2, 1e-1, 2e-1, 5e-1, 1});
  EXPECT_EQ(with_class(all, "stat")[1].text, "last 5.00×10⁻²");
}

TEST(LossSvg, NothingDrawableStillGivesLabelledAxesAndANote) {
  for (const std::vector<double>& losses :
       {std::vector<double>{}, std::vector<double>{0, -2, std::nan("")}}) {
    LossCurve c;
    for (std::size_t i = 0; i < losses.size(); ++i) c.iterations.push_back(double(i + 1));
    c.losses = losses;
    const std::vector<XmlElement> all = parse_xml(loss_svg(c));
    expect_finite_attributes(all);
    EXPECT_TRUE(with_class(all, "loss").empty());
    ASSERT_EQ(with_class(all, "note").size(), 1u);
    EXPECT_EQ(with_class(all, "note")[0].text, "no positive finite loss to draw");
    EXPECT_FALSE(tick_values(all).empty());
    EXPECT_FALSE(with_class(all, "x-tick").empty());
    EXPECT_EQ(with_class(all, "stat")[0].text, "first n/a");
  }
}

TEST(LossSvg, HugeRangesKeepAboutEightDecadeLabelsAndFiniteCoordinates) {
  LossCurve c;
  c.iterations = {1, 1e6};
  c.losses = {1e300, 1e-300};
  c.priors = {1e-320, 5e-324};  // denormals: drawable, so they set the range's bottom
  const std::vector<XmlElement> all = parse_xml(loss_svg(c));
  expect_finite_attributes(all);
  const std::vector<double> y = tick_values(all);
  ASSERT_GE(y.size(), 4u);
  EXPECT_LE(y.size(), 9u);
  for (double v : y) EXPECT_FALSE(std::isnan(v));
  EXPECT_LE(y.front(), 5e-324);
  EXPECT_GE(y.back(), 1e300);
  EXPECT_EQ(with_class(all, "prior").size(), 1u);  // both drawable: one line
  EXPECT_EQ(with_class(all, "x-tick").back().text, "1000000");
}

TEST(LossSvg, OnePointAndPriorsAndEscapedText) {
  LossCurve c;
  c.iterations = {7};
  c.losses = {0.5};
  c.priors = {0.01};
  c.title = "a <b> & \"c\" 'd'";
  c.levels = {{7, "<4³>"}};
  // One point: the x axis is centred on it (6 .. 8), not started at it.
  const std::vector<XmlElement> all = parse_xml(loss_svg(c));
  expect_finite_attributes(all);
  EXPECT_EQ(with_class(all, "title")[0].text, c.title);
  EXPECT_EQ(with_class(all, "level")[0].text, "<4³>");
  EXPECT_EQ(with_class(all, "loss")[0].name, "circle");
  EXPECT_EQ(with_class(all, "prior")[0].name, "circle");
  std::vector<std::string> legend;
  for (const XmlElement& e : with_class(all, "legend")) legend.push_back(e.text);
  EXPECT_EQ(legend, (std::vector<std::string>{"image loss (MSE)", "prior term"}));
  EXPECT_NEAR(tick_values(all).front(), 1e-2, 1e-15);
  EXPECT_EQ(tick_values(all).back(), 1);
  EXPECT_EQ(with_class(all, "stat")[2].text, "lowest 5.00×10⁻¹ (it. 7)");
  std::vector<std::string> x;
  for (const XmlElement& e : with_class(all, "x-tick")) x.push_back(e.text);
  EXPECT_EQ(x, (std::vector<std::string>{"6", "7", "8"}));
}

TEST(LossSvg, TheReaderRejectsMalformedXml) {
  for (const char* bad : {"<svg><text>a</svg>", "<svg a=1/>", "<svg>&nope;</svg>", "<a/><b/>",
                          "<svg>", "<svg a=\"1\" a=\"2\"/>", "<svg>x</svg>y"})
    EXPECT_THROW(parse_xml(bad), std::runtime_error) << bad;
  EXPECT_NO_THROW(parse_xml("<?xml version=\"1.0\"?>\n<svg a='1'><t>&amp;&#8722;</t></svg>\n"));
}

}  // namespace
}  // namespace ivr::test
