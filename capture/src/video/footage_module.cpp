// libcpgait_footage.so's entry: the table of its functions (cpgait/video/footage.h).
#include "cpgait/video/footage.h"

extern "C" __attribute__((visibility("default"))) const cpgait::video::FootageFunctions* cpgait_footage_functions() {
  using namespace cpgait::video;
  static const FootageFunctions functions{&capture_markers, &detect_videos,           &probe_video,
                                          &calibrate_cameras, &read_opencv_calibration, &detect_image_file};
  return &functions;
}
