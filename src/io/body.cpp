// The body on the lattice (SPEC §3, "The body, and what is not tissue") with ITK's filters. Its
// own translation unit: the morphology templates are heavy, and nothing else here needs them.
#include <itkAndImageFilter.h>
#include <itkBinaryBallStructuringElement.h>
#include <itkBinaryDilateImageFilter.h>
#include <itkBinaryFillholeImageFilter.h>
#include <itkBinaryMorphologicalOpeningImageFilter.h>
#include <itkBinaryThresholdImageFilter.h>
#include <itkConnectedComponentImageFilter.h>
#include <itkImage.h>
#include <itkRelabelComponentImageFilter.h>

#include <algorithm>

#include "hpcm/io.hpp"
#include "hpcm/model.hpp"

namespace hpcm::io {

namespace {
using HuImage = itk::Image<float, 3>;
using MaskImage = itk::Image<unsigned char, 3>;
using LabelImage = itk::Image<unsigned int, 3>;

// The radius is in lattice elements, not millimetres: the opening must cut what is thin for the
// simulation's links (a contact a few elements wide), at every --downsample; a millimetre radius
// would vanish on coarse lattices and erase the skin of fine ones.
constexpr unsigned kOpeningRadius = 2;

// The lattice as an ITK image on a unit grid (the filters work in index units).
HuImage::Pointer lattice_image(const Volume& lattice) {
  auto img = HuImage::New();
  HuImage::SizeType size;
  size[0] = static_cast<itk::SizeValueType>(lattice.dims.x);
  size[1] = static_cast<itk::SizeValueType>(lattice.dims.y);
  size[2] = static_cast<itk::SizeValueType>(lattice.dims.z);
  img->SetRegions(HuImage::RegionType(size));
  img->Allocate();
  std::copy(lattice.hu.begin(), lattice.hu.end(), img->GetBufferPointer());
  return img;
}
}  // namespace

std::vector<std::uint8_t> find_body(const Volume& lattice) {
  validate_volume(lattice, "body search");
  try {
    auto threshold = itk::BinaryThresholdImageFilter<HuImage, MaskImage>::New();
    threshold->SetInput(lattice_image(lattice));
    threshold->SetLowerThreshold(kBodyHu);  // not air (the §7 surface test)
    threshold->SetInsideValue(1);
    threshold->SetOutsideValue(0);

    using Ball = itk::BinaryBallStructuringElement<unsigned char, 3>;
    Ball ball;
    ball.SetRadius(kOpeningRadius);
    ball.CreateStructuringElement();
    auto opening = itk::BinaryMorphologicalOpeningImageFilter<MaskImage, MaskImage, Ball>::New();
    opening->SetInput(threshold->GetOutput());
    opening->SetKernel(ball);
    opening->SetForegroundValue(1);
    opening->SetBackgroundValue(0);

    auto components = itk::ConnectedComponentImageFilter<MaskImage, LabelImage>::New();
    components->SetInput(opening->GetOutput());
    components->SetFullyConnected(false);  // 6-connected, like the lattice's links
    auto relabel = itk::RelabelComponentImageFilter<LabelImage, LabelImage>::New();  // 1 = the largest
    relabel->SetInput(components->GetOutput());

    auto largest = itk::BinaryThresholdImageFilter<LabelImage, MaskImage>::New();
    largest->SetInput(relabel->GetOutput());
    largest->SetLowerThreshold(1);
    largest->SetUpperThreshold(1);
    largest->SetInsideValue(1);
    largest->SetOutsideValue(0);

    // The opening also shaves the body's own surface where it is sharper than the ball (skin
    // folds, the navel, edges at coarse lattices); a detached bit of skin would then be
    // anchored as an outside object. Give back what the opening took within its own radius of
    // the body (a dilation by the same ball, kept to the non-air elements); the contacts it cut
    // stay cut beyond that radius.
    auto grow = itk::BinaryDilateImageFilter<MaskImage, MaskImage, Ball>::New();
    grow->SetInput(largest->GetOutput());
    grow->SetKernel(ball);
    grow->SetForegroundValue(1);
    grow->SetBackgroundValue(0);
    auto regrown = itk::AndImageFilter<MaskImage, MaskImage, MaskImage>::New();
    regrown->SetInput1(grow->GetOutput());
    regrown->SetInput2(threshold->GetOutput());

    auto fill = itk::BinaryFillholeImageFilter<MaskImage>::New();  // lungs, bowel gas
    fill->SetInput(regrown->GetOutput());
    fill->SetForegroundValue(1);
    fill->SetFullyConnected(false);
    fill->Update();
    const unsigned char* mask = fill->GetOutput()->GetBufferPointer();
    return std::vector<std::uint8_t>(mask, mask + lattice.size());
  } catch (const itk::ExceptionObject& e) {
    throw Error(std::string("body search on the ") + std::to_string(lattice.dims.x) + "x" + std::to_string(lattice.dims.y) +
                "x" + std::to_string(lattice.dims.z) + " lattice failed: " + e.GetDescription());
  }
}

}  // namespace hpcm::io
