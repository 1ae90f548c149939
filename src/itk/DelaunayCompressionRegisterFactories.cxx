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
// Compiled into every program that links DelaunayCompression::DelaunayCompression (an INTERFACE source
// of the target): registers the .dcv image and mesh IO factories at start-up, so that ImageFileReader,
// ImageFileWriter, MeshFileReader and MeshFileWriter handle .dcv files with no code of the program's
// own. Being part of the program, it also keeps the linker from dropping the library.
#include "itkDCVImageIOFactory.h"
#include "itkDCVMeshIOFactory.h"

namespace
{
struct DelaunayCompressionFactoryRegistration
{
  DelaunayCompressionFactoryRegistration()
  {
    itk::DCVImageIOFactory::RegisterOneFactory();
    itk::DCVMeshIOFactory::RegisterOneFactory();
  }
};
const DelaunayCompressionFactoryRegistration delaunayCompressionFactoryRegistration;
} // namespace
