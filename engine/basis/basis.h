// fulgur::basis — virtual lights, basis intensities and their compressed storage
// (Dobashi et al. 2007, sections 5 and 6). The module's public header: it includes the topic
// headers, each of which may be included alone.
//
//  * basis/virtual_lights.h  the virtual-light grid (paper section 5)
//  * basis/haar.h            HaarTransform<T>: orthonormal 3D Haar, any grid size
//  * basis/half.h            float16 conversions (the compact storage precision)
//  * basis/compression.h     thresholding (paper section 6): compress_light(), retruncate()
//  * basis/fgb.h             the .fgb file: FgbWriter, FgbReader, load_fgb(), merge_fgb()
//  * basis/export.h          weighted sums of bases and their NRRD export
//
// docs/basis.md explains the choices; docs/fgb-format.md specifies the file byte by byte.
#pragma once

#include "basis/compression.h"
#include "basis/export.h"
#include "basis/fgb.h"
#include "basis/haar.h"
#include "basis/half.h"
#include "basis/virtual_lights.h"
