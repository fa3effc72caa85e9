#pragma once
// Small sampling kernels shared by tracking, rendering and the metrics.

#include <algorithm>
#include <array>
#include <cmath>

namespace flowvid::flow {

// Catmull-Rom (Keys, a = -0.5) weights for a sample at fraction t in [0, 1)
// between taps 1 and 2 of four taps 0..3. They sum to 1 and reproduce the
// taps exactly at t = 0, so whole-pixel shifts copy pixels unchanged.
inline std::array<float, 4> catmull_rom_weights(float t) {
    const float t2 = t * t, t3 = t2 * t;
    return {0.5f * (-t3 + 2.0f * t2 - t), 0.5f * (3.0f * t3 - 5.0f * t2 + 2.0f), 0.5f * (-3.0f * t3 + 4.0f * t2 + t),
            0.5f * (t3 - t2)};
}

// Feathering weight of patch pixel i of n along one axis: a raised cosine that
// falls to zero at the patch border (thesis 3.2.2: weights inversely related
// to the distance to the edges), evaluated at the pixel centre, so border
// pixels get small positive weights and overlapping patches blend smoothly.
// Tabulated (4096 steps, linear interpolation: error below 1e-6), because
// rendering and the editing correspondence evaluate it per pixel.
inline constexpr int kFeatherTableSteps = 4096;
struct FeatherTable {
    float value[kFeatherTableSteps + 2];
    FeatherTable() {
        for (int k = 0; k <= kFeatherTableSteps + 1; ++k) {
            const double s = std::sin(M_PI * std::min(k, kFeatherTableSteps) / kFeatherTableSteps);
            value[k] = static_cast<float>(s * s);
        }
    }
};
inline const FeatherTable kFeatherTable{};  // built once at start-up, no guard per call

inline float feather_weight(float i, int n) {
    const float u = (i + 0.5f) / static_cast<float>(n);
    if (!(u > 0.0f && u < 1.0f)) return 0.0f;
    const float r = u * kFeatherTableSteps;
    const int k = static_cast<int>(r);
    return kFeatherTable.value[k] + (r - static_cast<float>(k)) * (kFeatherTable.value[k + 1] - kFeatherTable.value[k]);
}

// Top-left pixel of the patch x patch block of whole pixels whose centre
// (top-left + (patch - 1) / 2) is nearest to `centre` along one axis. Bank
// patches are these blocks: "centred on the particle" to within half a pixel,
// and rendering at the same position puts every texel back on the pixel it
// came from, so plain synthesis copies the clip without resampling blur.
inline int patch_origin(double centre, int patch) {
    return static_cast<int>(std::floor(centre - (patch - 1) / 2.0 + 0.5));
}

}  // namespace flowvid::flow
