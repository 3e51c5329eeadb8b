#pragma once
/// \file config_keywords.hpp
/// viscd::Config (and the gl backend's GlOptions) as Python keywords: `lambda_=50, bits=32,
/// layout="plain"`. Enums are strings (bits also takes 16, 32, 64); an unknown keyword raises
/// TypeError naming it, a bad value ValueError naming the keyword and what it takes.

#include <pybind11/pybind11.h>

#include "viscd/config.hpp"
#include "viscd/gl.hpp"

namespace viscd::python {

namespace py = pybind11;

/// Applies `keywords` to `config` and `gl` (the gl_* keywords); sets `gl_given` when a gl_*
/// keyword was among them. Leaves both unchanged when it throws.
void apply_keywords(const py::kwargs& keywords, Config& config, GlOptions& gl, bool& gl_given);

/// Every Config field as the keyword that sets it, with its value (enums as strings).
[[nodiscard]] py::dict config_dict(const Config& config);

/// The docstring lines listing every keyword, its default and what it takes.
[[nodiscard]] const char* keywords_doc();

/// The keywords as (name, gl only, type as the stub writes it, default as a Python literal):
/// the module's _keyword_table(), which a test checks the type stub against.
[[nodiscard]] py::list keyword_table();

}  // namespace viscd::python
