// Moved to common/fullscreen.vert (shared by tsd and ssss); kept so tsd.py's path still works.
#include "common/fullscreen.vert"
