#pragma once
/// @file
/// The isovalue a scan opens at when neither the scene file nor the command line names one,
/// chosen from its modality and its values so that the first picture shows the anatomy:
/// - CT in HU: bone, 400 HU, what a clinician feels first;
/// - MR and PET (values without a fixed scale: MR intensities, PET in SUV or Bq/ml): the
///   triangle threshold of the volume's histogram, the knee where the background's peak (air,
///   most of the voxels) gives way to the body's long tail. Otsu's method was tried first: it
///   splits the body's own broad range in two whenever the body is a small part of the volume,
///   the usual case for a head or a whole-body PET, and hides part of the anatomy;
/// - anything else: the middle of the value range.

#include "vh/haptics/scalar_volume.h"
#include "vh/io/volume_loader.h"

namespace vh::runtime {

/// The triangle threshold of `field`'s values (G. W. Zack, W. E. Rogers, S. A. Latt, "Automatic
/// measurement of sister chromatid exchange frequency", J. Histochem. Cytochem. 25(7), 1977): in
/// a histogram of `bins` equal bins over [minValue, maxValue], the bin farthest from the line
/// joining the highest bin to the far end of the longer side. A volume of more than about 2
/// million voxels is sampled on a regular stride in each axis.
/// @return a value in [minValue, maxValue] (data units): the chosen bin's edge away from the
///         peak; the middle of the range for a constant volume.
double triangleThreshold(const haptics::ScalarVolume& field, int bins = 256);

/// Whether `volume`'s values are Hounsfield units: a CT, or a file that names HU as its unit.
bool inHounsfieldUnits(const io::LoadedVolume& volume);

/// The isovalue `volume` opens at (see the file comment). `volume.field` must be set.
double defaultIsovalue(const io::LoadedVolume& volume);

}  // namespace vh::runtime
