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
#ifndef dcvMemory_h
#define dcvMemory_h

// Internal to the compiled sources.
#if defined(__GLIBC__)
#  include <malloc.h>
#endif

namespace dcv
{

/** Gives the pages of freed memory back to the system, after a stage that freed volume-sized buffers.
 * glibc keeps them in its arenas (one per thread that allocated: OpenJPEG's, TBB's, the corners'
 * thread), where the next stage, often on another thread, cannot reuse them: the 5 mm CT series at
 * 0.125 bpv peaked at 358 MB with them kept (docs/profile.md). A no-op elsewhere. */
inline void
ReturnFreedMemory()
{
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

} // namespace dcv

#endif
