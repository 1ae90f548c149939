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
#include "dcvSlicerModule.h"
#include "dcvVideoLayer.h"

#include "dcvTools.h"

#include "itkMacro.h"

#include <CLI/CLI.hpp>
#include <expat.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <set>
#include <sstream>
#include <stdexcept>

namespace dcv::slicer
{
namespace
{
const std::set<std::string> &
KnownTags()
{
  static const std::set<std::string> tags{ "integer", "float",          "double",       "boolean",
                                           "string",  "integer-vector", "float-vector", "double-vector",
                                           "file",    "image",          "directory" };
  return tags;
}

bool
IsHeaderElement(const std::string & tag)
{
  return tag == "label" || tag == "description";
}

std::string
Trimmed(const std::string & s)
{
  const auto first = s.find_first_not_of(" \t\r\n");
  if (first == std::string::npos)
    return {};
  const auto last = s.find_last_not_of(" \t\r\n");
  return s.substr(first, last - first + 1);
}

std::string
WithoutDashes(const std::string & s)
{
  const auto first = s.find_first_not_of('-');
  return first == std::string::npos ? std::string() : s.substr(first);
}

/** The expat handlers' state: the open elements, the text of the innermost, the result. */
struct DescriptionReader
{
  std::vector<std::string> open;
  std::string              text;
  ModuleDescription        description;
  Parameter                current;
  std::string              error;

  void
  Start(const std::string & tag, const XML_Char ** attributes)
  {
    open.push_back(tag);
    text.clear();
    // Other spellings of a long flag (the hyphenated ones of earlier versions, which CTK's schema refuses
    // as a longflag), accepted as Slicer's generated parsers accept them.
    if (open.size() == 4 && open[1] == "parameters" && tag == "longflag")
    {
      for (const XML_Char ** a = attributes; a != nullptr && a[0] != nullptr; a += 2)
      {
        const std::string attribute = a[0];
        if (attribute == "alias" || attribute == "deprecatedalias")
        {
          std::istringstream in(a[1]);
          std::string        alias;
          while (std::getline(in, alias, ','))
          {
            alias = WithoutDashes(Trimmed(alias));
            if (!alias.empty())
              current.longflagAliases.push_back(alias);
          }
        }
      }
    }
    if (open.size() == 3 && open[1] == "parameters" && !IsHeaderElement(tag))
    {
      if (KnownTags().count(tag) == 0 && error.empty())
        error = "parameter type <" + tag + "> is not handled by this parser";
      current = Parameter{};
      current.tag = tag;
    }
  }
  void
  End()
  {
    const std::string value = Trimmed(text);
    text.clear();
    const std::string tag = open.back();
    if (open.size() == 2 && open[0] == "executable")
    {
      if (tag == "category")
        description.category = value;
      else if (tag == "title")
        description.title = value;
      else if (tag == "description")
        description.description = value;
      else if (tag == "version")
        description.version = value;
    }
    else if (open.size() == 3 && open[1] == "parameters" && !IsHeaderElement(tag))
    {
      description.parameters.push_back(current);
    }
    else if (open.size() == 4 && open[1] == "parameters" && !IsHeaderElement(open[2]))
    {
      if (tag == "name")
        current.name = value;
      else if (tag == "label")
        current.label = value;
      else if (tag == "description")
        current.description = value;
      else if (tag == "flag")
        current.flag = WithoutDashes(value);
      else if (tag == "longflag")
        current.longflag = WithoutDashes(value);
      else if (tag == "default")
      {
        current.defaultValue = value;
        current.hasDefault = true;
      }
      else if (tag == "channel")
        current.channel = value;
      else if (tag == "index")
      {
        try
        {
          current.index = std::stoi(value);
        }
        catch (const std::exception &)
        {
          error = "parameter '" + current.name + "': index '" + value + "' is not an integer";
        }
      }
    }
    open.pop_back();
  }
};

void XMLCALL
OnStart(void * data, const XML_Char * name, const XML_Char ** attributes)
{
  static_cast<DescriptionReader *>(data)->Start(name, attributes);
}

void XMLCALL
OnEnd(void * data, const XML_Char *)
{
  static_cast<DescriptionReader *>(data)->End();
}

void XMLCALL
OnText(void * data, const XML_Char * s, int length)
{
  static_cast<DescriptionReader *>(data)->text.append(s, std::size_t(length));
}

void
CheckDescription(const ModuleDescription & d)
{
  std::set<std::string> names;
  std::set<std::string> flags;
  std::vector<int>      indices;
  for (const Parameter & p : d.parameters)
  {
    if (p.name.empty())
      throw std::runtime_error("a <" + p.tag + "> parameter has no name");
    if (!names.insert(p.name).second)
      throw std::runtime_error("parameter name '" + p.name + "' is used twice");
    if (p.flag.size() > 1)
      throw std::runtime_error("parameter '" + p.name + "': a flag is one character, got '" + p.flag + "'");
    std::vector<std::string> spellings{ p.flag, p.longflag };
    spellings.insert(spellings.end(), p.longflagAliases.begin(), p.longflagAliases.end());
    for (const std::string & f : spellings)
    {
      if (!f.empty() && !flags.insert(f).second)
        throw std::runtime_error("flag '" + f + "' is used twice");
    }
    if (p.index >= 0)
    {
      if (!p.flag.empty() || !p.longflag.empty())
        throw std::runtime_error("parameter '" + p.name + "' has both an index and a flag");
      indices.push_back(p.index);
    }
    else if (!p.IsReturned() && p.flag.empty() && p.longflag.empty())
    {
      throw std::runtime_error("parameter '" + p.name + "' has neither an index nor a flag");
    }
  }
  std::sort(indices.begin(), indices.end());
  for (std::size_t i = 0; i < indices.size(); ++i)
  {
    if (indices[i] != int(i))
      throw std::runtime_error("the indices are not 0 to " + std::to_string(indices.size() - 1));
  }
}

std::string
Escaped(const std::string & s)
{
  std::string out;
  for (char c : s)
  {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else
      out += c;
  }
  return out;
}

bool
IsVector(const std::string & tag)
{
  return tag.size() > 7 && tag.compare(tag.size() - 7, 7, "-vector") == 0;
}

std::vector<std::string>
Split(const std::string & s)
{
  std::vector<std::string> out;
  std::string              item;
  std::istringstream       in(s);
  while (std::getline(in, item, ','))
    out.push_back(Trimmed(item));
  return out;
}

/** Checks that a value (each element of a vector) parses as the parameter's type; "" when it does. */
std::string
TypeError(const std::string & tag, const std::string & value)
{
  const std::string element = IsVector(tag) ? tag.substr(0, tag.size() - 7) : tag;
  if (element != "integer" && element != "float" && element != "double")
    return {};
  for (const std::string & item : IsVector(tag) ? Split(value) : std::vector<std::string>{ value })
  {
    std::size_t used = 0;
    try
    {
      if (element == "integer")
        (void)std::stoll(item, &used);
      else
        (void)std::stod(item, &used);
    }
    catch (const std::exception &)
    {
      used = 0;
    }
    if (item.empty() || used != item.size())
      return "'" + value + "' is not " + (element == "integer" ? "an integer" : "a number") +
             (IsVector(tag) ? " list (comma-separated)" : "");
  }
  return {};
}

std::string
Formatted(double value)
{
  std::ostringstream out;
  out << std::setprecision(10) << value;
  return out.str();
}
} // namespace

const Parameter *
ModuleDescription::Find(const std::string & name) const
{
  for (const Parameter & p : parameters)
  {
    if (p.name == name)
      return &p;
  }
  return nullptr;
}

ModuleDescription
ParseModuleDescription(const std::string & xml)
{
  DescriptionReader reader;
  XML_Parser        parser = XML_ParserCreate("UTF-8");
  XML_SetUserData(parser, &reader);
  XML_SetElementHandler(parser, OnStart, OnEnd);
  XML_SetCharacterDataHandler(parser, OnText);
  const bool        parsed = XML_Parse(parser, xml.data(), int(xml.size()), 1) == XML_STATUS_OK;
  const std::string message = parsed ? std::string()
                                     : std::string(XML_ErrorString(XML_GetErrorCode(parser))) + " at line " +
                                         std::to_string(XML_GetCurrentLineNumber(parser));
  XML_ParserFree(parser);
  if (!parsed)
    throw std::runtime_error("the module description is not well-formed XML: " + message);
  if (!reader.error.empty())
    throw std::runtime_error(reader.error);
  CheckDescription(reader.description);
  return reader.description;
}

const std::string &
Arguments::String(const std::string & name) const
{
  const auto it = m_Values.find(name);
  if (it == m_Values.end())
    throw std::logic_error("the module description has no input parameter '" + name + "'");
  return it->second;
}

double
Arguments::Double(const std::string & name) const
{
  return std::stod(String(name));
}

int64_t
Arguments::Integer(const std::string & name) const
{
  return std::stoll(String(name));
}

bool
Arguments::Boolean(const std::string & name) const
{
  return String(name) == "true";
}

std::vector<int64_t>
Arguments::Integers(const std::string & name) const
{
  std::vector<int64_t> out;
  for (const std::string & item : Split(String(name)))
    out.push_back(std::stoll(item));
  return out;
}

void
Arguments::Return(const std::string & name, double value)
{
  const Parameter * p = m_Description->Find(name);
  if (!p || !p->IsReturned() || (p->tag != "double" && p->tag != "float"))
    throw std::logic_error("the module description has no returned <double> '" + name + "'");
  m_Returned[name] = Formatted(value);
}

void
Arguments::Return(const std::string & name, int64_t value)
{
  const Parameter * p = m_Description->Find(name);
  if (!p || !p->IsReturned() || p->tag != "integer")
    throw std::logic_error("the module description has no returned <integer> '" + name + "'");
  m_Returned[name] = std::to_string(value);
}

std::string
Arguments::ReturnParameterText() const
{
  std::string text;
  for (const Parameter & p : m_Description->parameters)
  {
    if (!p.IsReturned())
      continue;
    const auto it = m_Returned.find(p.name);
    if (it == m_Returned.end())
      throw std::logic_error("the returned parameter '" + p.name + "' was not set");
    text += p.name + " = " + it->second + "\n";
  }
  return text;
}

int
RunModule(const char * xml, int argc, char * argv[], const std::function<void(Arguments &)> & body)
{
  const std::string program = argc > 0 ? std::filesystem::path(argv[0]).filename().string() : "module";
  ModuleDescription description;
  try
  {
    description = ParseModuleDescription(xml);
  }
  catch (const std::exception & e)
  {
    std::cerr << program << ": " << e.what() << std::endl;
    return 1;
  }
  for (int i = 1; i < argc; ++i)
  {
    if (std::string(argv[i]) == "--xml")
    {
      std::cout << xml;
      std::cout.flush();
      return 0;
    }
  }

  Arguments arguments;
  arguments.m_Description = &description;
  CLI::App                    app{ description.title + ": " + description.description, program };
  std::map<std::string, bool> switches;
  std::string                 returnParameterFile;
  std::string                 processInformation;
  try
  {
    app.add_flag("--xml", "Print the module description (XML) for 3D Slicer and exit");
    app.add_option("--returnparameterfile", returnParameterFile, "Write the returned values to this file");
    app.add_option("--processinformationaddress", processInformation, "Given by 3D Slicer; not used");
    std::vector<const Parameter *> positional;
    for (const Parameter & p : description.parameters)
    {
      if (p.index >= 0)
        positional.push_back(&p);
    }
    std::sort(positional.begin(), positional.end(), [](const Parameter * a, const Parameter * b) {
      return a->index < b->index;
    });
    for (const Parameter * p : positional)
    {
      app.add_option(p->name, arguments.m_Values[p->name], p->label + ": " + p->description)->required();
    }
    for (const Parameter & p : description.parameters)
    {
      if (p.index >= 0 || p.IsReturned())
        continue;
      std::string names = p.flag.empty() ? "" : "-" + p.flag;
      if (!p.longflag.empty())
        names += (names.empty() ? "--" : ",--") + p.longflag;
      for (const std::string & alias : p.longflagAliases)
        names += (names.empty() ? "--" : ",--") + alias;
      const std::string help = p.label + ": " + p.description;
      if (p.tag == "boolean")
      {
        switches[p.name] = p.defaultValue == "true";
        app.add_flag(names, switches[p.name], help);
        continue;
      }
      std::string & value = arguments.m_Values[p.name];
      value = p.defaultValue;
      auto * option = app.add_option(names, value, help);
      if (p.hasDefault)
        option->default_str(p.defaultValue);
      const std::string tag = p.tag;
      option->type_name(tag == "string"           ? "TEXT"
                        : tag == "integer-vector" ? "INT,INT,..."
                        : IsVector(tag)           ? "NUMBER,NUMBER,..."
                        : tag == "integer"        ? "INT"
                                                  : "NUMBER");
      option->check(CLI::Validator([tag](std::string & v) { return TypeError(tag, v); }, "", tag));
    }
  }
  catch (const CLI::Error & e)
  {
    std::cerr << program << ": the module description does not make a parser: " << e.what() << std::endl;
    return 1;
  }

  try
  {
    app.parse(argc, argv);
  }
  catch (const CLI::ParseError & e)
  {
    return app.exit(e) == 0 ? 0 : 1;
  }
  for (const auto & [name, on] : switches)
    arguments.m_Values[name] = on ? "true" : "false";

  try
  {
    body(arguments);
    if (!returnParameterFile.empty())
    {
      const std::string text = arguments.ReturnParameterText();
      std::ofstream     out(returnParameterFile, std::ios::trunc);
      out << text;
      out.close();
      if (!out)
        throw tools::Failure("cannot write the return parameter file " + tools::Quoted(returnParameterFile));
    }
  }
  catch (const itk::ExceptionObject & e)
  {
    std::cerr << program << ": " << e.GetDescription() << std::endl;
    return 1;
  }
  catch (const std::exception & e)
  {
    std::cerr << program << ": " << e.what() << std::endl;
    return 1;
  }
  return 0;
}

SlicerProgress::SlicerProgress(const std::string & name, const std::string & comment)
  : m_Name(name)
  , m_Start(std::chrono::steady_clock::now())
{
  std::printf("<filter-start>\n");
  std::fflush(stdout);
  std::printf("<filter-name>%s</filter-name>\n", Escaped(name).c_str());
  std::fflush(stdout);
  std::printf("<filter-comment>%s</filter-comment>\n", Escaped(comment).c_str());
  std::fflush(stdout);
  std::printf("</filter-start>\n");
  std::fflush(stdout);
  Print(0.0);
}

SlicerProgress::~SlicerProgress()
{
  if (!m_Ended)
  {
    std::printf("<filter-end>\n<filter-name>%s</filter-name>\n</filter-end>\n", Escaped(m_Name).c_str());
    std::fflush(stdout);
  }
}

void
SlicerProgress::Print(double value)
{
  std::printf("<filter-progress>%.4f</filter-progress>\n", value);
  std::fflush(stdout);
  m_Printed = value;
}

void
SlicerProgress::Report(double fraction, double from, double to)
{
  const double                value = from + std::clamp(fraction, 0.0, 1.0) * (to - from);
  std::lock_guard<std::mutex> lock(m_Mutex);
  if (!m_Ended && value >= m_Printed + 0.005 && value < 1.0)
    Print(value);
}

void
SlicerProgress::End()
{
  std::lock_guard<std::mutex> lock(m_Mutex);
  if (m_Ended)
    return;
  Print(1.0);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_Start).count();
  std::printf("<filter-end>\n");
  std::fflush(stdout);
  std::printf("<filter-name>%s</filter-name>\n", Escaped(m_Name).c_str());
  std::fflush(stdout);
  std::printf("<filter-time>%.3f</filter-time>\n", seconds);
  std::fflush(stdout);
  std::printf("</filter-end>\n");
  std::fflush(stdout);
  m_Ended = true;
}

std::function<void(double)>
SlicerProgress::Stage(double from, double to)
{
  return [this, from, to](double fraction) { Report(fraction, from, to); };
}

EncoderOptions
EncoderOptionsFrom(const Arguments & arguments)
{
  EncoderOptions o;
  o.psnr = arguments.Double("psnr");
  o.bitsPerVoxel = o.psnr > 0.0 ? 0.0 : arguments.Double("bitsPerVoxel");
  try
  {
    o.mode = ParseMode(arguments.String("mode"));
  }
  catch (const std::invalid_argument & e)
  {
    throw tools::Failure(std::string("--mode: ") + e.what());
  }
  o.residualLayer = !arguments.Boolean("noResidualLayer");
  o.videoLayer = !arguments.Boolean("noVideoLayer");
  try
  {
    o.videoCodecs = ParseVideoCodecs(arguments.String("videoCodec"));
  }
  catch (const std::invalid_argument & e)
  {
    throw tools::Failure(std::string("--videoCodec: ") + e.what());
  }
  o.quantizationStep = arguments.Double("quantizationStep");
  o.domainSigma = arguments.Double("domainSigma");
  o.rangeSigma = arguments.Double("rangeSigma");
  o.alpha = arguments.Double("alpha");
  const std::vector<int64_t> scale = arguments.Integers("scale");
  if (scale.size() != 3)
    throw tools::Failure("Scale (--scale) needs 3 integers SX,SY,SZ, got '" + arguments.String("scale") + "'");
  for (std::size_t d = 0; d < 3; ++d)
  {
    if (scale[d] < 0 || scale[d] > MaximumGridScale)
      throw tools::Failure("Scale (--scale) must be 1 to " + std::to_string(MaximumGridScale) +
                           " on each axis, or 0 on all: automatic, got " + std::to_string(scale[d]));
    o.scale[d] = int32_t(scale[d]);
  }
  try
  {
    CheckOptions(o);
  }
  catch (const std::invalid_argument & e)
  {
    throw tools::Failure(e.what());
  }
  return o;
}

void
ReturnEncoderFigures(Arguments & arguments, const EncoderResult & result)
{
  const double voxels = double(result.header.size.NumberOfVoxels());
  arguments.Return("outputPSNR", result.psnr);
  arguments.Return("outputBytes", int64_t(result.bytes.size()));
  arguments.Return("outputBitsPerVoxel", double(result.bytes.size()) * 8.0 / voxels);
  arguments.Return("outputPoints", int64_t(result.header.numberOfPoints));
}

} // namespace dcv::slicer
