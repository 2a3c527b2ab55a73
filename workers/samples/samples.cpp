#include "samples/samples.h"

namespace mm::samples {

std::vector<SamplePart> sample_parts() {
  return {{"chamfered_block", chamfered_block()},
          {"plate_with_holes", plate_with_holes()},
          {"flanged_cylinder", flanged_cylinder()}};
}

}  // namespace mm::samples
