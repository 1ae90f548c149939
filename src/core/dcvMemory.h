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
 * 0.125 bpv peaked at 265 MiB with them kept (docs/profile.md, "Memory"). A no-op elsewhere. */
inline void
ReturnFreedMemory()
{
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

/** Serves allocations of 8 MiB and more from mappings of their own, returned to the system when freed
 * (process-wide, from the first encoding on). glibc's own threshold rises up to 32 MiB as such mappings
 * are freed: the engine's vectors of several MB then land in the arenas among CGAL's cells, and the
 * holes they leave stay resident (norm-256 at 0.25 bpv: 120 to 200 MB free in the arenas). Below 8 MiB
 * the encoder's buffers of a range of cells, made again and again, would cost a page fault a page (1 MiB:
 * twice the faults on flair-mr). The top of a heap is kept up to 64 MiB, as glibc does at its highest
 * threshold. A no-op elsewhere. */
inline void
MapLargeAllocations()
{
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 8 << 20);
  mallopt(M_TRIM_THRESHOLD, 64 << 20);
#endif
}

} // namespace dcv

#endif
