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
#ifndef dcvWrappingCheck_h
#define dcvWrappingCheck_h

// Helpers of the C++ files that cmake/DelaunayCompressionWrappingCheck.cmake generates from wrapping/.
#include "itkSmartPointer.h"

#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>
#include <type_traits>

namespace dcvWrappingCheck
{

template <typename T, typename = void>
struct HasNew : std::false_type
{};
// Its own New() (itkNewMacro), not one inherited from a superclass (ImageToMeshFilter has MeshSource's).
template <typename T>
struct HasNew<T, std::void_t<decltype(T::New())>> : std::is_same<decltype(T::New()), itk::SmartPointer<T>>
{};

/** Creates a wrapped class as Python's New() would, and checks the name it reports (itkTypeMacro),
 * which ITK's Python layer shows; returns 1 if created, 0 for a class without New(). */
template <typename T>
int
Create(const char * wrappedName, const char * className)
{
  if constexpr (HasNew<T>::value)
  {
    const auto object = T::New();
    if (object.IsNull() || std::strcmp(object->GetNameOfClass(), className) != 0)
    {
      std::cerr << wrappedName << ": New() gave "
                << (object.IsNull() ? std::string("nothing") : std::string(object->GetNameOfClass())) << ", not a "
                << className << std::endl;
      std::exit(EXIT_FAILURE);
    }
    return 1;
  }
  else
  {
    return 0;
  }
}

/** How many of Ts are T. */
template <typename T, typename... Ts>
constexpr int
Count()
{
  return (0 + ... + int(std::is_same<T, Ts>::value));
}

} // namespace dcvWrappingCheck

#endif
