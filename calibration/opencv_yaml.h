// The subset of YAML that OpenCV's FileStorage writes for a rig or a noise model, checked before OpenCV
// parses a file: OpenCV 4.6's YAML parser loops forever or throws std::length_error on some malformed files
// (found by fuzz_noise_yaml and fuzz_rig_yaml, seeds regress_* in fuzz/corpus/), so a file outside the subset
// is refused first.
#pragma once

#include <string>

namespace rangebayes {

// Throws Error naming `path` and the line unless the file is: a first line `%YAML:1.0` (or `%YAML 1.0`), a
// line `---`, then lines that are blank, comments (`#`), `key: value` (key a C identifier; value a number, a
// word, a quoted string, `!!opencv-matrix`, a `[ ... ]` flow sequence of numbers and quoted strings that may
// continue over lines, or nothing), or `- item` lines indented under a `key:` without a value; no tabs, no
// `{ }`, no further document markers. `what` names the kind of file in the message ("rig file", "noise model").
void CheckOpenCvYamlSubset(const std::string& path, const std::string& what);

}  // namespace rangebayes
