// Mean angular error of face normals (docs/design.md §7): the quality measure of the denoising literature, used by
// `rangebayes eval`, the learned-prior objective reports and the smoothing benchmarks and tests.
#pragma once

#include "core/mesh.h"

namespace rangebayes {

// Mean angular error (degrees) between the face normals of `result` and `ground_truth`: mean over faces, not
// area weighted. Requires the same faces (same F) and vertex count; throws Error otherwise. Faces degenerate in
// either mesh are left out (and counted in *skipped when given); 0 when no face is left.
double MeanAngularErrorDeg(const Mesh& result, const Mesh& ground_truth, int* skipped = nullptr);

}  // namespace rangebayes
