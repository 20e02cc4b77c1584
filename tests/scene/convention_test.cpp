// convention_test.cpp — docs/design.md conventions: axes, cell centres, box, rays, image files.
#include <gtest/gtest.h>
#ifdef IVR_TEST_IMAGE_MODULE  // built with the image module: read its files back
#include <OpenImageIO/imageio.h>
#endif

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "reference/design_formulas.hpp"
#include "test_support.hpp"

namespace ivr::test {
namespace {

// Absolute tolerance on f32 images with values <= 1 and optical depths <= 1.5 along exactly
// placed rays: a few ulp per sample plus the float store.
constexpr double kTol = 2e-6;

// A zero volume with one voxel of density 1, absorption, sigma = a·d.
Scene single_voxel_scene(glm::ivec3 dims, glm::ivec3 at, double a) {
  Scene s;
  s.volume.nx = dims.x;
  s.volume.ny = dims.y;
  s.volume.nz = dims.z;
  s.volume.data.assign(s.volume.voxel_count(), 0.0f);
  s.volume.data[(std::size_t(at.z) * dims.y + at.y) * dims.x + at.x] = 1.0f;
  s.model = Model::absorption;
  s.tf.extinction_scale = a;
  s.integrator.min_transmittance = 0;
  return s;
}

// Expected image of a single-voxel scene whose orthographic, axis-aligned pixels all run along
// voxel-centre lines (asserted): along the line through the dense voxel's centre the density is
// a hat of height 1 and half-width h (or 1 in the clamped border half-voxel, then the same ramp),
// so tau = a·h_axis; on every other centre line the density is exactly 0.
// Returns the (column, row) of the one dark pixel.
glm::ivec2 expect_single_voxel_image(const Scene& s, const Image& img, int v, glm::ivec3 at) {
  const Camera& cam = s.cameras[v];
  const glm::dvec3 h = s.voxel_size();
  glm::ivec2 dark(-1);
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const Ray r = design_ray(cam, x, y);
      int axis = -1;
      bool through = true;
      for (int k = 0; k < 3; ++k) {
        if (std::abs(r.dir[k]) > 0.5) {
          axis = k;
          continue;
        }
        const double u = (r.origin[k] - s.box_min[k]) / h[k] - 0.5;  // voxel-centre coordinate
        EXPECT_NEAR(u, std::round(u), 1e-9) << "setup: pixel not on a voxel-centre line";
        through = through && std::lround(u) == at[k];
      }
      if (axis < 0) {
        ADD_FAILURE() << "setup: camera not axis-aligned";
        return dark;
      }
      if (through) {
        EXPECT_EQ(dark, glm::ivec2(-1)) << "two pixels through one voxel";
        dark = {x, y};
      }
      const double want = through ? std::exp(-s.tf.extinction_scale * h[axis]) : 1.0;
      EXPECT_NEAR(img.at(v, y, x, 0), want, kTol) << where(v, y, x);
    }
  return dark;
}

// ---------------------------------------------------------------------------------------------

// X=5, Y=3, Z=4 with one dense voxel at (3, 0, 2): any flipped axis moves the dark pixel (a
// flipped y would put it on row 0, not 2; y = 1 of 3 could not tell). Isotropic voxels h = 1/8
// (box given) so that step 0.5 puts sample boundaries on centre planes and the hat is exact.
TEST(Convention, SingleVoxelLandsOnTheRightPixelForEachAxis) {
  const glm::ivec3 dims(5, 3, 4), at(3, 0, 2);
  Scene s = single_voxel_scene(dims, at, 4.0);
  s.box_max = glm::dvec3(dims) / 16.0;
  s.box_min = -s.box_max;
  struct Case {
    Camera cam;
    glm::ivec2 pixel;  // hand-derived from docs/design.md (comments)
  } cases[] = {
      // Down -z, up y: forward (0,0,-1), right = forward × up = (1,0,0), up' = (0,1,0):
      // column = x = 3, row 0 = largest y, so row = Y-1-y = 2.
      {ortho({0, 0, 2}, {0, 1, 0}, 5, 3, 0.375), {3, 2}},
      // Along -x, up y: forward (-1,0,0), right = (0,0,-1), up' = (0,1,0):
      // column counts -z, so column = Z-1-z = 1; row = Y-1-y = 2.
      {ortho({2, 0, 0}, {0, 1, 0}, 4, 3, 0.375), {1, 2}},
      // Along -y, up -z: forward (0,-1,0), right = (1,0,0), up' = (0,0,-1):
      // column = x = 3; row 0 = smallest z, so row = z = 2.
      {ortho({0, 2, 0}, {0, 0, -1}, 5, 4, 0.5), {3, 2}},
  };
  for (const Case& c : cases) {
    s.cameras = {c.cam};
    const Image img = render_checked(s, Precision::f32, 0.5);
    EXPECT_EQ(expect_single_voxel_image(s, img, 0, at), c.pixel)
        << "eye " << c.cam.eye.x << "," << c.cam.eye.y << "," << c.cam.eye.z;
    EXPECT_NEAR(img.at(0, c.pixel.y, c.pixel.x, 0), std::exp(-4.0 / 8), kTol);  // tau = a·h
  }
}

// Ramp along x (v_x = 0.25 + 0.125x, exact in float), X=8, Y=2, Z=4 in the default box (h = 1/8).
Scene ramp_scene() {
  Scene s;
  s.volume.nx = 8;
  s.volume.ny = 2;
  s.volume.nz = 4;
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 8; ++x) s.volume.data.push_back(float(0.25 + 0.125 * x));
  set_default_box(s);
  s.model = Model::absorption;
  s.tf.extinction_scale = 2;
  s.integrator.min_transmittance = 0;
  return s;
}

// Values at cell centres: with W = X pixels over exactly the box width, pixel x's ray runs
// along voxel centre x, where the density is v_x for the whole depth L_z = 0.5.
TEST(Convention, ValuesSitAtCellCentres) {
  Scene s = ramp_scene();
  ASSERT_EQ(s.box_max, glm::dvec3(0.5, 0.125, 0.25));
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 8, 2, 0.25)};  // width 0.25·8/2 = 1
  const Image img = render_checked(s, Precision::f32);
  for (int y = 0; y < 2; ++y)
    for (int x = 0; x < 8; ++x) {
      ASSERT_NEAR(design_ray(s.cameras[0], x, y).origin.x, -0.5 + (x + 0.5) / 8, 1e-15);
      EXPECT_NEAR(img.at(0, y, x, 0), std::exp(-2 * (0.25 + 0.125 * x) * 0.5), kTol)
          << where(0, y, x);
    }
}

// 2X+1 pixels over (X + 1/2)·h: pixel k's ray sits at x = box_min + k·h/2, alternately on a
// voxel centre (odd k) and on the boundary between two cells (even k), which sees the average.
TEST(Convention, CellBoundariesSeeTheAverage) {
  Scene s = ramp_scene();
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 17, 1, 1.0625 / 17)};
  const Image img = render_checked(s, Precision::f32);
  auto v = [](int i) { return 0.25 + 0.125 * i; };
  for (int k = 1; k < 16; ++k) {  // k = 0 and 16 graze the faces x = ±0.5
    ASSERT_NEAR(design_ray(s.cameras[0], k, 0).origin.x, -0.5 + k / 16.0, 1e-15);
    const double d = k % 2 ? v((k - 1) / 2) : (v(k / 2 - 1) + v(k / 2)) / 2;
    EXPECT_NEAR(img.at(0, 0, k, 0), std::exp(-2 * d * 0.5), kTol) << "pixel " << k;
  }
}

TEST(Convention, DefaultBoxIsCentredProportionalLongestSideOne) {
  Scene s;
  s.volume.nx = 10;
  s.volume.ny = 20;
  s.volume.nz = 5;
  s.volume.spacing = {1, 1, 3};  // extent (10, 20, 15): y is longest
  set_default_box(s);
  EXPECT_EQ(s.box_min, glm::dvec3(-0.25, -0.5, -0.375));
  EXPECT_EQ(s.box_max, glm::dvec3(0.25, 0.5, 0.375));
  EXPECT_EQ(s.voxel_size(), glm::dvec3(0.05, 0.05, 0.15));  // proportional to spacing

  s.volume.spacing = {2, 0.5, 1};  // extent (20, 10, 5): x is longest
  set_default_box(s);
  EXPECT_EQ(s.box_max, glm::dvec3(0.5, 0.25, 0.125));
  EXPECT_EQ(s.box_min, -s.box_max);

  // The same through a scene file; "dims" is [X, Y, Z].
  const std::string dir = test::temp_dir("convention_default_box");
  const std::string camera = R"("cameras": [{"eye": [0, 0, 2], "target": [0, 0, 0], "up": [0, 1, 0],
                                "fov_y": 40, "width": 8, "height": 8}])";
  const Scene a =
      parse_scene(R"({"volume": {"synthetic": "sphere", "dims": [10, 20, 5], "spacing": [1, 1, 3]},
                                 "model": "absorption", )" +
                      camera + "}",
                  dir);
  EXPECT_EQ(a.volume.nx, 10);
  EXPECT_EQ(a.volume.ny, 20);
  EXPECT_EQ(a.volume.nz, 5);
  EXPECT_EQ(a.volume.data.size(), 1000u);
  EXPECT_EQ(a.box_min, glm::dvec3(-0.25, -0.5, -0.375));
  EXPECT_EQ(a.box_max, glm::dvec3(0.25, 0.5, 0.375));
  const Scene b = parse_scene(
      R"({"volume": {"synthetic": "sphere", "dims": [10, 20, 5]}, )" + camera + "}", dir);
  EXPECT_EQ(b.box_max, glm::dvec3(0.25, 0.5, 0.125));  // unit spacing: proportional to dims
  EXPECT_EQ(b.box_min, -b.box_max);
}

// The renderer uses that box: dims (2, 4, 8) → box 0.25 x 0.5 x 1, seen down -z as a tall
// rectangle (columns 3-4, rows 2-5 of 8 x 8 pixels of 1/8) — a transposed image would be wide.
TEST(Convention, DefaultBoxSilhouetteIsNotTransposed) {
  Scene s;
  s.volume.nx = 2;
  s.volume.ny = 4;
  s.volume.nz = 8;
  s.volume.data.assign(s.volume.voxel_count(), 1.0f);
  set_default_box(s);
  s.model = Model::absorption;
  s.tf.extinction_scale = 1.5;
  s.integrator.min_transmittance = 0;
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 8, 8, 1.0)};
  const Image img = render_checked(s, Precision::f32);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) {
      const double L = chord(design_ray(s.cameras[0], x, y), s.box_min, s.box_max);
      const bool inside = x >= 3 && x <= 4 && y >= 2 && y <= 5;
      ASSERT_NEAR(L, inside ? 1.0 : 0.0, 1e-12) << where(0, y, x);
      EXPECT_NEAR(img.at(0, y, x, 0), std::exp(-1.5 * L), kTol) << where(0, y, x);
    }
}

// fov 90 (tan = 1), eye (0,0,2) looking at the origin: pixel (0,0) of a W x H image has
// sx = 1/W - 1, sy = 1 - 1/H and direction forward + sx·(W/H)·right + sy·up'. A small box of
// constant density is placed where that ray crosses z = 0; only pixel (0,0) may see it, with
// tau = sigma·(its chord). Using H/W for the aspect would miss the box.
TEST(Convention, PerspectiveCornerRayAndAspect) {
  struct Case {
    int w, h;
    glm::dvec3 hit;                        // eye + 2·(sx·W/H, sy, -1)
  } cases[] = {{4, 2, {-3.0, 1.0, 0.0}},   // sx = -0.75, W/H = 2, sy = 0.5
               {2, 4, {-0.5, 1.5, 0.0}}};  // sx = -0.5, W/H = 0.5, sy = 0.75
  for (const Case& c : cases) {
    Scene s;
    s.volume.nx = s.volume.ny = s.volume.nz = 2;
    s.volume.data.assign(8, 1.0f);
    s.box_min = c.hit - glm::dvec3(0.1, 0.1, 0.5);
    s.box_max = c.hit + glm::dvec3(0.1, 0.1, 0.5);
    s.model = Model::absorption;
    s.tf.extinction_scale = 4;
    s.integrator.min_transmittance = 0;
    Camera cam;
    cam.eye = {0, 0, 2};
    cam.target = {0, 0, 0};
    cam.up = {0, 1, 0};
    cam.fov_y = 90;
    cam.width = c.w;
    cam.height = c.h;
    s.cameras = {cam};
    const Ray corner = design_ray(cam, 0, 0);
    const glm::dvec3 at_z0 = corner.origin + (2 / -corner.dir.z) * corner.dir;
    ASSERT_NEAR(glm::length(at_z0 - c.hit), 0, 1e-12);  // the hand value matches docs/design.md's ray
    const Image img = render_checked(s, Precision::f32);
    for (int y = 0; y < c.h; ++y)
      for (int x = 0; x < c.w; ++x) {
        const double L = chord(design_ray(cam, x, y), s.box_min, s.box_max);
        EXPECT_EQ(L > 0, x == 0 && y == 0) << where(0, y, x);
        EXPECT_NEAR(img.at(0, y, x, 0), std::exp(-4 * L), kTol)
            << where(0, y, x) << " " << c.w << "x" << c.h;
      }
    EXPECT_LT(img.at(0, 0, 0, 0), 0.5);  // the chord is ~0.25 long: clearly dark
  }
}

// Several cameras in one scene: images come out as (views, H, W, C) in camera order, and the
// .npy written by save_image_npy has exactly that shape and those values.
TEST(Convention, ViewsComeOutInCameraOrderAndNpyShape) {
  const glm::ivec3 at(3, 0, 1);
  Scene s = single_voxel_scene({4, 4, 4}, at, 4.0);
  set_default_box(s);                                   // unit cube, h = 1/4
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 4, 4, 1),    // dark at (x=3, row Y-1-y=3)
               ortho({2, 0, 0}, {0, 1, 0}, 4, 4, 1),    // dark at (col Z-1-z=2, row 3)
               ortho({0, 2, 0}, {0, 0, -1}, 4, 4, 1)};  // dark at (x=3, row z=1)
  const glm::ivec2 want[] = {{3, 3}, {2, 3}, {3, 1}};
  const Image img = render_checked(s, Precision::f32, 0.5);
  ASSERT_EQ(img.views, 3);
  ASSERT_EQ(img.channels, 1);
  for (int v = 0; v < 3; ++v)
    EXPECT_EQ(expect_single_voxel_image(s, img, v, at), want[v]) << "view " << v;

  const std::string path = test::temp_dir("convention_npy") + "/views.npy";
  save_image_npy(path, img);
  const NpyArray back = load_npy(path);
  EXPECT_EQ(back.shape, (std::vector<std::size_t>{3, 4, 4, 1}));
  ASSERT_EQ(back.data.size(), img.pixels.size());
  for (std::size_t i = 0; i < img.pixels.size(); ++i)
    ASSERT_EQ(back.data[i], double(img.pixels[i])) << i;

  // Emission–absorption gives four channels in the same layout.
  s.model = Model::emission_absorption;
  s.cameras.resize(2);
  const Image rgba = render_checked(s, Precision::f32, 0.5);
  save_image_npy(path, rgba);
  EXPECT_EQ(load_npy(path).shape, (std::vector<std::size_t>{2, 4, 4, 4}));
}

// The documented PNG rule, with the sRGB curve written out here.
double srgb(double v) {
  return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
}
int tone_map_here(double linear) {
  return int(std::lround(255 * srgb(std::clamp(linear, 0.0, 1.0))));
}

TEST(Convention, ToneMapIsClampSrgbRound) {
  EXPECT_EQ(tone_map_8bit(0.0), 0);
  EXPECT_EQ(tone_map_8bit(1.0), 255);
  EXPECT_EQ(tone_map_8bit(-0.5), 0);    // clamped
  EXPECT_EQ(tone_map_8bit(7.0), 255);   // clamped
  EXPECT_EQ(tone_map_8bit(0.002), 7);   // linear segment: 255·12.92·0.002 = 6.59
  EXPECT_EQ(tone_map_8bit(0.18), 118);  // 255·(1.055·0.18^(1/2.4) - 0.055) = 117.65
  EXPECT_EQ(tone_map_8bit(0.5), 188);   // 187.52
  for (int i = 0; i <= 1000; ++i) {
    const double v = -0.05 + 1.1 * i / 1000.0;
    EXPECT_EQ(int(tone_map_8bit(v)), tone_map_here(v)) << v;
  }
}

#ifdef IVR_TEST_IMAGE_MODULE
struct ReadBack {
  int width = 0, height = 0, channels = 0;
  OIIO::TypeDesc format;
  std::vector<float> values;  // as float (PNG: the 8-bit codes, not normalised)
};
ReadBack read_image(const std::string& path) {
  ReadBack r;
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    ADD_FAILURE() << "OpenImageIO cannot open " << path << ": " << OIIO::geterror();
    return r;
  }
  const OIIO::ImageSpec& spec = in->spec();
  r.width = spec.width;
  r.height = spec.height;
  r.channels = spec.nchannels;
  r.format = spec.format;
  const std::size_t n = std::size_t(r.width) * r.height * r.channels;
  if (spec.format == OIIO::TypeDesc::UINT8) {
    std::vector<unsigned char> bytes(n);
    EXPECT_TRUE(in->read_image(0, 0, 0, r.channels, OIIO::TypeDesc::UINT8, bytes.data()))
        << in->geterror();
    r.values.assign(bytes.begin(), bytes.end());
  } else {
    r.values.resize(n);
    EXPECT_TRUE(in->read_image(0, 0, 0, r.channels, OIIO::TypeDesc::FLOAT, r.values.data()))
        << in->geterror();
  }
  in->close();
  return r;
}

// PNG: 8-bit RGB (emission–absorption) or grey (absorption) by tone_map_8bit; EXR: every
// channel as float, bit-equal. A non-square image and view 1 of 2 catch transposes and
// wrong view offsets.
TEST(Convention, PngAndExrReadBackThroughOpenImageIO) {
  Scene s = ramp_scene();  // default box 1 x 0.25 x 0.5
  s.cameras = {ortho({0, 0, 2}, {0, 1, 0}, 7, 3, 0.5), ortho({2, 0, 0}, {0, 1, 0}, 7, 3, 0.5)};
  const std::string dir = test::temp_dir("convention_images");
  for (Model m : {Model::absorption, Model::emission_absorption}) {
    s.model = m;
    s.tf.color_scale = 3;
    // Misses show the background: > 1 (clamped), mid-grey and tiny (linear sRGB segment).
    s.background = m == Model::absorption ? glm::dvec3(1.5) : glm::dvec3(1.5, 0.4, 0.002);
    const Image img = render_checked(s, Precision::f32);
    for (int view : {0, 1}) {
      const std::string stem = dir + "/m" + std::to_string(int(m)) + "v" + std::to_string(view);
      save_image_file(stem + ".png", img, view);
      save_image_file(stem + ".exr", img, view);

      const ReadBack png = read_image(stem + ".png");
      const int png_channels = m == Model::absorption ? 1 : 3;
      EXPECT_EQ(png.width, 7);
      EXPECT_EQ(png.height, 3);
      ASSERT_EQ(png.channels, png_channels);
      EXPECT_EQ(png.format, OIIO::TypeDesc::UINT8);
      for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 7; ++x)
          for (int c = 0; c < png_channels; ++c)
            EXPECT_EQ(png.values[(y * 7 + x) * png_channels + c],
                      tone_map_here(img.at(view, y, x, c)))
                << stem << ".png " << where(view, y, x) << " channel " << c;

      const ReadBack exr = read_image(stem + ".exr");
      EXPECT_EQ(exr.width, 7);
      EXPECT_EQ(exr.height, 3);
      ASSERT_EQ(exr.channels, img.channels);
      EXPECT_EQ(exr.format, OIIO::TypeDesc::FLOAT);
      for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 7; ++x)
          for (int c = 0; c < img.channels; ++c)
            EXPECT_EQ(exr.values[(y * 7 + x) * img.channels + c], img.at(view, y, x, c))
                << stem << ".exr " << where(view, y, x) << " channel " << c;
    }
    // The two views differ (the scene is not symmetric), so a wrong view offset would show.
    EXPECT_NE(img.at(0, 1, 3, 0), img.at(1, 1, 3, 0));
  }
}
#endif  // IVR_TEST_IMAGE_MODULE

}  // namespace
}  // namespace ivr::test
