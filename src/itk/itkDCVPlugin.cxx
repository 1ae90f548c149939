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
// The ITK plugin: ITK loads every shared library of the directories in ITK_AUTOLOAD_PATH and calls
// its itkLoad(). This one gives the .dcv image IO factory and registers the mesh IO factory, so that
// a program that does not link the module still reads and writes .dcv files.
#include "DelaunayCompressionExport.h"
#include "itkDCVImageIOFactory.h"
#include "itkDCVMeshIOFactory.h"

extern "C" DelaunayCompression_EXPORT itk::ObjectFactoryBase *
                                      itkLoad()
{
  itk::DCVMeshIOFactory::RegisterOneFactory();
  // ITK takes a reference of its own; ours, a static of this library, keeps the factory alive as long as
  // the library is loaded and releases it when ITK closes the library (an extra Register() never undone
  // leaked it: LeakSanitizer, PluginLoadsThroughITK_AUTOLOAD_PATH).
  static const itk::DCVImageIOFactory::Pointer factory = itk::DCVImageIOFactory::New();
  return factory.GetPointer();
}
