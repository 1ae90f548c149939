/*=========================================================================
 *
 *  Copyright NumFOCUS
 *
 *  Licensed under the Apache License, Version 2.0 (the "License");
 *  you may not use this file except in compliance with the License.
 *  You may obtain a copy of the License at
 *
 *         http://www.apache.org/licenses/LICENSE-2.0.txt
 *
 *  Unless required by applicable law or agreed to in writing, software
 *  distributed under the License is distributed on an "AS IS" BASIS,
 *  WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
 *  See the License for the specific language governing permissions and
 *  limitations under the License.
 *
 *=========================================================================*/
// dcv phantom: the 3D Shepp-Logan head phantom, the demo's volume.
#include "dcvCommand.h"
#include "dcvPhantom.h"

namespace dcv::tools
{
namespace
{
struct PhantomOptions
{
  std::string output;
  int         size{ 128 };
  bool        force{ false };
};

void
Phantom(const PhantomOptions & p)
{
  if (p.size < 2 || p.size > 1024)
  {
    throw UsageError("--size must be 2 to 1024, got " + std::to_string(p.size));
  }
  CheckOutput(p.output, p.force);
  using ImageType = itk::Image<uint8_t, 3>;
  const std::vector<uint8_t> voxels = SheppLoganPhantom(GridSize{ p.size, p.size, p.size });
  auto                       image = ImageType::New();
  ImageType::SizeType        extent;
  extent.Fill(itk::SizeValueType(p.size));
  image->SetRegions(extent);
  image->Allocate();
  std::copy(voxels.begin(), voxels.end(), image->GetBufferPointer());
  WriteVolume(image.GetPointer(), p.output, p.force);
}

const RegisterCommand
  phantom{ { "phantom", "Write a 3D Shepp-Logan head phantom (uint8)", [](CLI::App & command) -> std::function<void()> {
              auto p = std::make_shared<PhantomOptions>();
              command.add_option("OUTPUT", p->output, "Output volume (format from its extension)")->required();
              command.add_option("--size,-s", p->size, "Voxels along each axis")->capture_default_str();
              command.add_flag("--force,-f", p->force, "Overwrite OUTPUT if it exists");
              return [p] { Phantom(*p); };
            } } };
} // namespace
} // namespace dcv::tools
