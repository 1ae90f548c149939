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
#include "dcvTools.h"

#include "itkImageIOFactory.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <mutex>
#include <system_error>

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/statvfs.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace dcv::tools
{
namespace
{
/** ITK's ImageIO for `path`, or null; GDCM's library is loaded (registering its ImageIO) only when no other
 * format takes the name, as for a .dcm file. */
itk::ImageIOBase::Pointer
CreateImageIO(const std::string & path, itk::IOFileModeEnum mode)
{
  if (auto io = itk::ImageIOFactory::CreateImageIO(path.c_str(), mode))
  {
    return io;
  }
  try
  {
    GDCM();
  }
  catch (const Failure &)
  {
    return nullptr; // told as a name no format takes
  }
  return itk::ImageIOFactory::CreateImageIO(path.c_str(), mode);
}
} // namespace

itk::ImageIOBase::Pointer
ReadVolumeHeader(const std::string & path)
{
  if (!fs::exists(path))
  {
    throw Failure("cannot read " + Quoted(path) + ": no such file");
  }
  if (fs::is_directory(path))
  {
    throw Failure("cannot read " + Quoted(path) + ": it is a directory, not a volume file");
  }
  auto io = CreateImageIO(path, itk::IOFileModeEnum::ReadMode);
  if (!io)
  {
    throw Failure("cannot read " + Quoted(path) + ": not an image format ITK knows (NRRD, NIfTI, MetaImage, ...)");
  }
  io->SetFileName(path);
  try
  {
    io->ReadImageInformation();
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure("cannot read " + Quoted(path) + ": " + e.GetDescription());
  }
  const unsigned int dimensions = io->GetNumberOfDimensions();
  if (dimensions != 3)
  {
    throw Failure(Quoted(path) + " is a " + std::to_string(dimensions) + "D image; a 3D volume is needed");
  }
  if (io->GetNumberOfComponents() != 1)
  {
    throw Failure(Quoted(path) + " has " + std::to_string(io->GetNumberOfComponents()) + " components per voxel (" +
                  itk::ImageIOBase::GetPixelTypeAsString(io->GetPixelType()) + " pixels); a scalar volume is needed");
  }
  for (unsigned int d = 0; d < 3; ++d)
  {
    if (io->GetDimensions(d) < 2)
    {
      throw Failure(Quoted(path) + " is " + std::to_string(io->GetDimensions(0)) + "x" +
                    std::to_string(io->GetDimensions(1)) + "x" + std::to_string(io->GetDimensions(2)) +
                    " voxels; at least 2 voxels along each axis are needed");
    }
  }
  return io;
}

PixelType
ReadVolumePixelType(const std::string & path)
{
  const auto io = ReadVolumeHeader(path);
  try
  {
    return itk::DCVPixelType(io->GetComponentType(), Quoted(path));
  }
  catch (const itk::ExceptionObject & e)
  {
    throw Failure(e.GetDescription());
  }
}

VolumeInput
OpenVolume(const std::string & path, const std::string & series, bool resample, DicomHeaderMode header)
{
  VolumeInput v;
  v.path = path;
  if (!fs::exists(path))
  {
    throw Failure("cannot read " + Quoted(path) + ": no such file");
  }
  if (!IsDicomInput(path))
  {
    if (!series.empty())
    {
      throw Failure("--series chooses a DICOM series; " + Quoted(path) + " is not DICOM");
    }
    v.type = ReadVolumePixelType(path);
    return v;
  }
  v.dicom = FindDicomSeries(path, series, v.skipped);
  v.resampling = CheckDicomSlices("the DICOM series " + Quoted(path), ReadDicomSlices(v.dicom), resample);
  v.type = DicomPixelType(v.dicom);
  v.metadata = DicomMetadata(v.dicom);
  if (v.resampling.needed)
  {
    // The files' headers describe slices the resampled volume does not have: only the fixed list.
    for (const auto & file : v.dicom.files)
      CheckDicomPixelData(file);
    v.metadata.emplace_back("Resampled", v.resampling.description); // the DICOM writer's derivation says so
  }
  else
  {
    v.metadata.emplace_back(DicomHeaderKey, ReadDicomHeaders(v.dicom.files, header));
  }
  return v;
}

void
CheckOutput(const std::string & output, bool force, bool dcvFile)
{
  // The name first: a usage error is told before the state of the disk.
  if (dcvFile)
  {
    if (fs::path(output).extension() != ".dcv")
    {
      throw UsageError("cannot write " + Quoted(output) + ": a compressed volume's file name ends in .dcv");
    }
  }
  else if (!CreateImageIO(output, itk::IOFileModeEnum::WriteMode))
  {
    throw UsageError("cannot write " + Quoted(output) +
                     ": no image format is known for that file name "
                     "(use .nrrd, .nii.gz, .mha, ...)");
  }
  CheckOutputPath(output, force);
}

void
CheckOutputPath(const std::string & output, bool force)
{
  if (fs::exists(output) && !force)
  {
    throw Failure(Quoted(output) + " already exists; use --force to overwrite it");
  }
  if (fs::is_directory(output))
  {
    throw Failure(Quoted(output) + " is a directory");
  }
  const fs::path parent = fs::absolute(output).parent_path();
  if (!fs::is_directory(parent))
  {
    throw Failure("cannot write " + Quoted(output) + ": directory " + Quoted(parent.string()) + " does not exist");
  }
}

void
CheckOutputIsNotInput(const std::vector<std::string> & inputs, const std::string & output)
{
  std::error_code error;
  for (const auto & input : inputs)
  {
    if (fs::equivalent(input, output, error))
    {
      throw UsageError("cannot write " + Quoted(output) + ": it is the input " + Quoted(input) +
                       "; give another output name");
    }
  }
}

namespace
{
/** Formats whose header names its data file: renaming the header would break it. */
bool
IsSeveralFiles(const fs::path & target)
{
  std::string extension = target.extension().string();
  if (extension == ".gz")
  {
    extension = target.stem().extension().string() + extension;
  }
  for (const char * e : { ".mhd", ".hdr", ".img", ".img.gz", ".hdr.gz", ".nhdr" })
  {
    if (extension == e)
      return true;
  }
  return false;
}

/** The temporary files and directories a signal removes. A fixed table of plain characters, so that the
 * handler reads it without allocating or locking; a slot is claimed with a compare-exchange, so that
 * batch's threads can register at the same time. */
struct TemporarySlot
{
  std::atomic<int> state{ 0 }; // 0 free, 1 being filled or emptied, 2 registered
  bool             directory{ false };
  char             path[4096];
};
TemporarySlot temporarySlots[64];

/** Removes a directory and the files in it (one level: what a writer put there) with calls a signal
 * handler may make: open, unlinkat, rmdir, and the getdents64 system call (Linux; readdir() may allocate). */
void
RemoveDirectoryFromSignal(const char * path)
{
  const int fd = ::open(path, O_RDONLY | O_DIRECTORY);
  if (fd >= 0)
  {
    alignas(8) char buffer[4096];
    for (;;)
    {
      const long n = ::syscall(SYS_getdents64, fd, buffer, sizeof(buffer));
      if (n <= 0)
        break;
      for (long at = 0; at < n;)
      {
        // struct linux_dirent64: inode (8), offset (8), record length (2), type (1), name.
        unsigned short length;
        std::memcpy(&length, buffer + at + 16, sizeof(length));
        const char * name = buffer + at + 19;
        if (!(name[0] == '.' && (name[1] == '\0' || (name[1] == '.' && name[2] == '\0'))))
          ::unlinkat(fd, name, 0);
        at += length;
      }
    }
    ::close(fd);
  }
  ::rmdir(path);
}

extern "C" void
RemoveTemporariesAndDie(int signal)
{
  const int saved = errno;
  for (auto & slot : temporarySlots)
  {
    if (slot.state.load() == 2)
    {
      if (slot.directory)
        RemoveDirectoryFromSignal(slot.path);
      else
        ::unlink(slot.path);
    }
  }
  errno = saved;
  // Die of the signal, as without the handler, so that the caller sees what happened.
  ::signal(signal, SIG_DFL);
  ::raise(signal);
}

void
InstallSignalCleanup()
{
  static std::once_flag once;
  std::call_once(once, [] {
    for (int s : { SIGINT, SIGTERM, SIGHUP })
    {
      // Only where nobody chose otherwise: an ignored SIGHUP (nohup) or an application's own handler stays.
      struct sigaction current = {};
      if (::sigaction(s, nullptr, &current) == 0 && current.sa_handler == SIG_DFL)
      {
        struct sigaction action = {};
        action.sa_handler = RemoveTemporariesAndDie;
        sigemptyset(&action.sa_mask);
        ::sigaction(s, &action, nullptr);
      }
    }
  });
}

} // namespace

RemovedOnSignal::RemovedOnSignal(const std::string & path, bool directory)
{
  InstallSignalCleanup();
  const std::string absolute = fs::absolute(path).string(); // the handler must not depend on the directory
  if (absolute.size() >= sizeof(TemporarySlot::path))
    return;
  for (int i = 0; i < int(std::size(temporarySlots)); ++i)
  {
    TemporarySlot & slot = temporarySlots[i];
    int             expected = 0;
    if (slot.state.compare_exchange_strong(expected, 1))
    {
      std::memcpy(slot.path, absolute.c_str(), absolute.size() + 1);
      slot.directory = directory;
      slot.state.store(2);
      m_Slot = i;
      return;
    }
  }
  // A full table: that output is still removed on failure, only not on a signal.
}

RemovedOnSignal::~RemovedOnSignal()
{
  if (m_Slot >= 0)
    temporarySlots[m_Slot].state.store(0);
}

namespace
{
std::string
ErrorText(int error)
{
  return std::error_code(error, std::generic_category()).message();
}

/** rename(), but unless `replace` failing with EEXIST when `to` exists, decided atomically by the file
 * system: renameat2 RENAME_NOREPLACE, or where a file system lacks it (EINVAL) a hard link, which never
 * replaces, then the unlink of the old name. Returns 0 or an errno value. */
int
MoveFile(const std::string & from, const std::string & to, bool replace)
{
  if (replace)
    return ::rename(from.c_str(), to.c_str()) == 0 ? 0 : errno;
  if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE) == 0)
    return 0;
  if (errno != EINVAL && errno != ENOSYS)
    return errno;
  if (::link(from.c_str(), to.c_str()) != 0)
    return errno;
  ::unlink(from.c_str());
  return 0;
}
} // namespace

PendingOutput::PendingOutput(const std::string & output, bool force, bool itkFormat)
  : m_Output(output)
  , m_Force(force)
{
  const fs::path    target(output);
  const std::string prefix = ".dcv-" + std::to_string(::getpid()) + "-" + target.filename().string();
  if (itkFormat && IsSeveralFiles(target))
  {
    // A header names its data file: both are written in a directory of their own, under their names.
    m_Directory = (target.parent_path() / (prefix + ".tmp")).string();
    std::error_code error;
    fs::remove_all(m_Directory, error);
    if (!fs::create_directory(m_Directory, error))
    {
      throw Failure("cannot write " + Quoted(output) + ": cannot create a directory beside it (" + error.message() +
                    ")");
    }
    m_Path = (fs::path(m_Directory) / target.filename()).string();
    m_Registration = std::make_unique<RemovedOnSignal>(m_Directory, true);
    return;
  }
  // ITK picks the format from the extension: the temporary keeps it.
  m_Path = (target.parent_path() / (itkFormat ? prefix : prefix + ".tmp")).string();
  m_Registration = std::make_unique<RemovedOnSignal>(m_Path, false);
}

PendingOutput::~PendingOutput()
{
  if (!m_Committed)
  {
    std::error_code ignored;
    fs::remove_all(m_Directory.empty() ? m_Path : m_Directory, ignored);
  }
}

std::vector<fs::path>
PendingOutput::Files() const
{
  std::vector<fs::path> files; // the header last
  if (m_Directory.empty())
  {
    files.emplace_back(m_Path);
  }
  else
  {
    std::error_code error;
    for (const auto & entry : fs::directory_iterator(m_Directory, error))
    {
      if (entry.path() != fs::path(m_Path))
        files.push_back(entry.path());
    }
    std::sort(files.begin(), files.end());
    files.emplace_back(m_Path);
  }
  return files;
}

void
PendingOutput::Commit()
{
  const std::vector<fs::path> files = Files(); // what to move, the header last
  std::error_code             error;
  if (!fs::is_regular_file(m_Path, error))
  {
    throw Failure("cannot write " + Quoted(m_Output) + ": the writer made no file");
  }
  const fs::path           parent = fs::path(m_Output).parent_path();
  std::vector<std::string> moved;
  for (const auto & file : files)
  {
    const std::string to = file == fs::path(m_Path) ? m_Output : (parent / file.filename()).string();
    const int         e = MoveFile(file.string(), to, m_Force);
    if (e != 0)
    {
      // The files of a format of several files go together or not at all.
      for (const auto & name : moved)
        fs::remove(name, error);
      if (e == EEXIST)
      {
        throw Failure("cannot write " + Quoted(m_Output) + ": " + Quoted(to) +
                      " appeared while it was being written (another run?); it is kept, use --force to overwrite it");
      }
      throw Failure("cannot write " + Quoted(m_Output) + ": cannot rename the temporary file (" + ErrorText(e) + ")");
    }
    moved.push_back(to);
  }
  if (!m_Directory.empty())
  {
    fs::remove(m_Directory, error);
  }
  m_Committed = true;
}

std::string
PendingOutput::LimitReached() const
{
  const std::string directory = fs::absolute(m_Output).parent_path().string();
  struct statvfs    disk = {};
  if (::statvfs(directory.c_str(), &disk) == 0 && (::geteuid() == 0 ? disk.f_bfree : disk.f_bavail) == 0)
  {
    return "the disk is full (no space left on the device of " + Quoted(directory) + ")";
  }
  struct rlimit size = {};
  if (::getrlimit(RLIMIT_FSIZE, &size) == 0 && size.rlim_cur != RLIM_INFINITY)
  {
    std::vector<fs::path> written{ fs::path(m_Path) };
    std::error_code       error;
    if (!m_Directory.empty())
    {
      for (const auto & entry : fs::directory_iterator(m_Directory, error))
        written.push_back(entry.path());
    }
    for (const auto & file : written)
    {
      const auto bytes = fs::file_size(file, error);
      if (!error && bytes >= size.rlim_cur)
      {
        return "the file reached the size limit of the process (" + std::to_string(size.rlim_cur) +
               " bytes, ulimit -f)";
      }
    }
  }
  return {};
}

bool
FileEndsWith(const std::string & path, const void * bytes, std::size_t n)
{
  std::ifstream file(path, std::ios::binary | std::ios::ate);
  if (!file)
    return false;
  const std::streamoff size = file.tellg();
  if (size < std::streamoff(n) || !file.seekg(size - std::streamoff(n)))
    return false;
  std::vector<char> block(std::size_t(1) << 20);
  for (std::size_t done = 0; done < n;)
  {
    const std::size_t part = std::min(block.size(), n - done);
    if (!file.read(block.data(), std::streamsize(part)) ||
        std::memcmp(block.data(), static_cast<const char *>(bytes) + done, part) != 0)
      return false;
    done += part;
  }
  return true;
}

void
WriteOutputBytes(const std::string & output, const std::vector<uint8_t> & bytes, bool force)
{
  PendingOutput pending(output, force, false);
  // O_EXCL: a temporary of the same name (a run with a recycled PID, killed) is not written into.
  const int fd = ::open(pending.Path().c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0)
  {
    throw Failure("cannot write " + Quoted(output) + ": " + ErrorText(errno));
  }
  std::size_t done = 0;
  int         error = 0;
  while (done < bytes.size())
  {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR)
      continue;
    if (n <= 0)
    {
      error = n < 0 ? errno : EIO;
      break;
    }
    done += std::size_t(n);
  }
  if (error == 0 && ::fsync(fd) != 0 && errno != EINVAL)
    error = errno;
  if (::close(fd) != 0 && error == 0)
    error = errno;
  if (error != 0)
  {
    const std::string limit = error == ENOSPC || error == EFBIG ? pending.LimitReached() : std::string();
    throw Failure("cannot write " + Quoted(output) + ": " + ErrorText(error) +
                  (limit.empty() ? "" : " (" + limit + ")"));
  }
  pending.Commit();
}

CompressedFile
ParseCompressedBytes(const std::vector<uint8_t> & bytes, const std::string & name)
{
  CompressedFile file;
  file.name = name;
  file.size = bytes.size();
  ParseFile(bytes, file.name, file.header, file.payload);
  return file;
}

} // namespace dcv::tools
