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
#ifndef itkDCVMeshIOFactory_h
#define itkDCVMeshIOFactory_h

#include "DelaunayCompressionExport.h"
#include "itkObjectFactoryBase.h"

namespace itk
{

/** \class DCVMeshIOFactory
 * \brief Creates DCVMeshIO objects, so that MeshFileReader and MeshFileWriter handle .dcv files once the factory is
 * registered (RegisterOneFactory(), or automatically through the module's FACTORY_NAMES MeshIO::DCV in a build
 * inside ITK).
 * \ingroup DelaunayCompression
 */
class DelaunayCompression_EXPORT DCVMeshIOFactory : public ObjectFactoryBase
{
public:
  ITK_DISALLOW_COPY_AND_MOVE(DCVMeshIOFactory);

  using Self = DCVMeshIOFactory;
  using Superclass = ObjectFactoryBase;
  using Pointer = SmartPointer<Self>;
  using ConstPointer = SmartPointer<const Self>;

  const char *
  GetITKSourceVersion() const override;
  const char *
  GetDescription() const override;

  itkFactorylessNewMacro(Self);
  itkTypeMacro(DCVMeshIOFactory, ObjectFactoryBase);

  /** Registers the factory once (later calls do nothing). */
  static void
  RegisterOneFactory();

protected:
  DCVMeshIOFactory();
  ~DCVMeshIOFactory() override = default;
};

} // namespace itk

#endif
