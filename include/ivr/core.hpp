// ivr/core.hpp — the core C++ API of ivr in one include (what the CLI, tests and benchmarks use;
// its types may change between versions: for a stable ABI use ivr/ivr.hpp or ivr/ivr.h).
#pragma once
#include "ivr/calibrate.hpp"
#include "ivr/device.hpp"
#include "ivr/differentiate.hpp"
#include "ivr/error.hpp"
#include "ivr/gradient.hpp"
#include "ivr/optimize.hpp"
#include "ivr/phantom.hpp"
#include "ivr/planner.hpp"
#include "ivr/render.hpp"
#include "ivr/scene.hpp"
#include "ivr/tangents.hpp"
#include "ivr/tolerance.hpp"
#include "ivr/tomo.hpp"
#include "ivr/version.h"
#include "ivr/volume_io.hpp"
