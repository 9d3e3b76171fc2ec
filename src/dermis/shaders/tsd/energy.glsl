// Moved to common/energy.glsl (shared by every skin technique); kept so old includes still work.
#include "common/energy.glsl"
