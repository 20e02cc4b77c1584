// ivr/ivr.hpp — the C++ API of ivr in one include.
#pragma once
#include "ivr/device.hpp"
#include "ivr/error.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"
#include "ivr/version.h"
#include "ivr/volume_io.hpp"
#include "ivr/gradient.hpp"
#include "ivr/tangents.hpp"
