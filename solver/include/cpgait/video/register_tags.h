#pragma once
// Registration of a tag set from a static trial, as OpenSim's MarkerPlacer does for markers: IK
// with the approximate tag poses gives the subject's pose, then each tag's pose on its body is
// re-estimated from where its corners were actually triangulated (Kabsch fit of the square to the
// corners averaged over the trial, in the body's frame).
#include <string>
#include <vector>

#include "cpgait/capture/trc.h"
#include "cpgait/model/model.h"
#include "cpgait/video/tag_markers.h"
#include "cpgait/video/tag_set.h"

namespace cpgait::video {

struct TagRegistrationOptions {
  int min_frames = 3;  // a tag needs all four corners in this many frames to be moved
};

struct TagRegistrationSummary {
  std::vector<int> moved;                 // tag ids re-placed
  std::vector<int> unchanged;             // not seen enough; kept as given
  std::vector<double> shift_m;            // per moved tag: how far its centre moved
  std::vector<double> turn_rad;           // per moved tag: how far it turned
  double marker_rms_before_m = 0, marker_rms_after_m = 0;  // IK marker RMS on the static trial
  std::string BriefReport() const;
};

// `markers`: the static trial's tag corners (capture_markers output). Throws InputError for a tag
// body the model lacks.
TagSet register_tag_set(const Model& model, const TagSet& approximate, const MarkerTrial& markers,
                        const TagRegistrationOptions& options = {}, TagRegistrationSummary* summary = nullptr);

}  // namespace cpgait::video
