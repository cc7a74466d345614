// Exact-mode geometry in one include: point in closed solid, triangle/mesh against box, closedness.
// See each header for the method and its guarantees.
#pragma once

#include "engine/geometry/exact_predicates.h"
#include "engine/geometry/mesh_edges.h"
#include "engine/geometry/solid_classifier.h"
#include "engine/geometry/triangle_box.h"
