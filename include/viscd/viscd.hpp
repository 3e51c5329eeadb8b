#pragma once
/// \file viscd.hpp
/// Umbrella header: everything a user of viscd needs.

#include "viscd/config.hpp"
#include "viscd/detector.hpp"
#include "viscd/frame.hpp"
#include "viscd/gl.hpp"
#include "viscd/io.hpp"
#include "viscd/result.hpp"
#include "viscd/scene.hpp"
#include "viscd/types.hpp"
#include "viscd/version.hpp"
