// ivr/ivr.hpp — the C++ API of ivr in one include.
#pragma once
#include "ivr/calibrate.hpp"
#include "ivr/device.hpp"
#include "ivr/differentiate.hpp"
#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "ivr/planner.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"
#include "ivr/tangents.hpp"
#include "ivr/version.h"
#include "ivr/volume_io.hpp"
