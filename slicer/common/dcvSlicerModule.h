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
#ifndef dcvSlicerModule_h
#define dcvSlicerModule_h

// What the 3D Slicer command-line modules (DCVCompress, DCVDecompress, DCVApproximate) share: the
// module description (the XML each prints for --xml, the one source of its parameters), a parser of
// the arguments built from that description, the return parameter file, progress in the form Slicer
// reads on stdout, and the encoder's options from the parameters. GenerateCLP does this in Slicer's
// own build; it is not packaged for Debian.
#include "dcvEncoder.h"

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace dcv::slicer
{

/** One parameter of a module description. */
struct Parameter
{
  std::string tag; // integer, float, double, boolean, string, integer-vector, double-vector, file, image
  std::string name;
  std::string label;
  std::string description;
  std::string flag;     // without the dash; empty when none
  std::string longflag; // without the dashes; empty when none
  std::string defaultValue;
  std::string channel; // input, output, or empty
  int         index{ -1 };
  bool        hasDefault{ false };
  /** The longflag's alias and deprecatedalias attributes (without dashes): other spellings it accepts. */
  std::vector<std::string> longflagAliases;

  /** A value the module gives back through the return parameter file: an output with neither
   * index nor flag (Slicer passes nothing for it). */
  bool
  IsReturned() const
  {
    return channel == "output" && index < 0 && flag.empty() && longflag.empty();
  }
};

/** A module description: the header elements Slicer shows, and the parameters in document order. */
struct ModuleDescription
{
  std::string            category;
  std::string            title;
  std::string            description;
  std::string            version;
  std::vector<Parameter> parameters;

  const Parameter *
  Find(const std::string & name) const;
};

/** Parses a module description; throws std::runtime_error on malformed XML, a parameter without a
 * name, a duplicate name, flag or index, indices that are not 0..n-1, or a parameter type this
 * parser does not handle. */
ModuleDescription
ParseModuleDescription(const std::string & xml);

/** The parsed arguments of one run, and what the run gives back. */
class Arguments
{
public:
  /** The value of a parameter as given, or its default (empty when it has none). */
  const std::string &
  String(const std::string & name) const;
  double
  Double(const std::string & name) const;
  int64_t
  Integer(const std::string & name) const;
  bool
  Boolean(const std::string & name) const;
  std::vector<int64_t>
  Integers(const std::string & name) const;

  /** Sets a returned value (a parameter whose IsReturned() holds; std::logic_error otherwise). */
  void
  Return(const std::string & name, double value);
  void
  Return(const std::string & name, int64_t value);

  /** The text of the return parameter file: one "name = value" line per returned parameter, in the
   * description's order (std::logic_error when one was not set). */
  std::string
  ReturnParameterText() const;

  const ModuleDescription &
  Description() const
  {
    return *m_Description;
  }

private:
  friend int
  RunModule(const char * xml, int argc, char * argv[], const std::function<void(Arguments &)> & body);
  const ModuleDescription *          m_Description{ nullptr };
  std::map<std::string, std::string> m_Values;
  std::map<std::string, std::string> m_Returned;
};

/** The main() of a module: `--xml` prints the description; otherwise the arguments are parsed as the
 * description declares them (positional parameters by index, the others by -flag or --longflag, booleans
 * as switches, plus --returnparameterfile FILE and --processinformationaddress ADDRESS, which Slicer
 * may pass), body runs, and the returned values are written to the return parameter file. Errors go to
 * stderr as "TITLE: message"; the exit status is 0 on success (and for --xml, --help), else 1. */
int
RunModule(const char * xml, int argc, char * argv[], const std::function<void(Arguments &)> & body);

/** Progress as Slicer reads it on a module's stdout: a filter-start block, filter-progress values rising
 * from 0 to 1, and a filter-end block, each line flushed. Fractions passed to Report() are mapped into
 * [from, to] of the whole run; a value is printed only when it has risen by at least 0.005, so the
 * printed values never fall whatever the caller reports. */
class SlicerProgress
{
public:
  SlicerProgress(const std::string & name, const std::string & comment);
  ~SlicerProgress();
  /** `fraction` of the stage that spans [from, to] of the run. */
  void
  Report(double fraction, double from = 0.0, double to = 1.0);
  /** Ends the run: progress 1, then the filter-end block (once; the destructor does it otherwise). */
  void
  End();
  /** A callback for EncoderOptions::progress that reports into [from, to]. */
  std::function<void(double)>
  Stage(double from, double to);

private:
  void
                                        Print(double value);
  std::string                           m_Name;
  std::chrono::steady_clock::time_point m_Start;
  std::mutex                            m_Mutex;
  double                                m_Printed{ -1.0 };
  bool                                  m_Ended{ false };
};

/** The encoder's options from the parameters DCVCompress and DCVApproximate share (bpv, psnr, mode,
 * noResidualLayer, noVideoLayer, videoCodec, step, domainSigma, rangeSigma, alpha, scale): a PSNR above 0 replaces the
 * bit rate; every value checked as the library checks it (dcv::tools::Failure naming the option). */
EncoderOptions
EncoderOptionsFrom(const Arguments & arguments);

/** The figures of an encoded file both modules return: PSNR, bytes, bits per voxel, points. */
void
ReturnEncoderFigures(Arguments & arguments, const EncoderResult & result);

} // namespace dcv::slicer

#endif
