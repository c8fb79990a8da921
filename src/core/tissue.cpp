#include "hpcm/tissue.hpp"

#include <cmath>
#include <sstream>

namespace hpcm {

const char* tissue_name(Tissue t) { return tissue_name(static_cast<int>(t)); }
const char* tissue_name(int t) {
  static const char* names[kTissueCount] = {"air", "skin_fat", "muscle_organ", "bone"};
  return (t >= 0 && t < kTissueCount) ? names[t] : "unknown";
}

void TissueThresholds::validate() const {
  const float t[3] = {t1, t2, t3};
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(t[i])) {
      std::ostringstream m;
      m << "tissue.t" << (i + 1) << " = " << t[i] << " must be a finite HU value";
      throw Error(m.str());
    }
  if (!(t1 < t2 && t2 < t3)) {
    std::ostringstream m;
    m << "tissue thresholds (t1, t2, t3) = (" << t1 << ", " << t2 << ", " << t3 << ") must be strictly increasing";
    throw Error(m.str());
  }
}

}  // namespace hpcm
