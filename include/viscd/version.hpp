#pragma once
/// \file version.hpp
namespace viscd {
/// Library version, semantic: major.minor.patch.
inline constexpr int kVersionMajor = 0;
inline constexpr int kVersionMinor = 1;
inline constexpr int kVersionPatch = 0;
}  // namespace viscd
