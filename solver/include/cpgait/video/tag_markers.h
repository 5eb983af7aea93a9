#pragma once
// A tag set's corners on a model: the model side of AprilTag capture (capture/ knows tags, not models).
#include <string>

#include "cpgait/model/model.h"
#include "cpgait/video/tag_set.h"

namespace cpgait::video {

// A copy of `model` with the tag corners added as markers (replacing markers of the same name), so
// IK runs on triangulated tag corners. Throws InputError for a body the model lacks.
Model with_tag_markers(const Model& model, const TagSet& set, const std::string& set_name = "tag set");

}  // namespace cpgait::video
