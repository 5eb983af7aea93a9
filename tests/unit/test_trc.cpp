#include <gtest/gtest.h>
#include "cpgait/capture/trc.h"
TEST(Trc, Placeholder) { EXPECT_EQ(cpgait::metres_per_unit("mm"), 1e-3); }
