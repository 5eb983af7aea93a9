#pragma once
// Writes a Model as an OpenSim document: the document it was read from (Model::source), in that
// document's own version, with what scaling changes taken from the Model - bodies' masses, centres of
// mass and inertias; joint frames' translations (3.x location_in_parent/location, 4.x the joints'
// PhysicalOffsetFrames) and translation functions (wrapped in MultiplierFunction, as OpenSim writes
// them); path points and moving points' functions; wrap objects' translations and dimensions;
// muscles' optimal fibre and tendon slack lengths; and the marker set, written whole. Everything else
// (geometry, other forces, controllers) is copied as it is. OpenSim opens what this writes.
#include <string>

#include "cpgait/model/model.h"

namespace cpgait {

struct OsimWriteOptions {
  std::string model_name;       // the <Model name>; empty keeps the source document's
  std::string source_document;  // the document's text; empty reads Model::source
};

// The document's text. Throws InputError naming the source document and element where the Model does
// not fit it (an element the Model lacks, a marker or point on a model-level offset frame).
std::string osim_document(const Model& model, const OsimWriteOptions& options = {});

// The model's markers as an OpenSim 4 MarkerSet document (the MarkerPlacer's output_marker_file),
// which the reader's marker_set_file takes.
std::string marker_set_document(const Model& model);

}  // namespace cpgait
