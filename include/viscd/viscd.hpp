#pragma once
/// \file viscd.hpp
/// Umbrella header: everything an engine linking viscd::viscd needs. The scene generators and
/// file readers/writers of viscd::tools are not included: include viscd/scene.hpp and
/// viscd/io.hpp for those.

#include "viscd/config.hpp"
#include "viscd/cuda.hpp"
#include "viscd/detector.hpp"
#include "viscd/executor.hpp"
#include "viscd/frame.hpp"
#include "viscd/gl.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"
#include "viscd/version.hpp"
