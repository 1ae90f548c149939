#!/usr/bin/env python3
# Copyright NumFOCUS; licensed under the Apache License, Version 2.0 (LICENSE).
"""Runs a 3D Slicer command-line module the way Slicer runs one, for the tests (dcvSlicerModuleTest.cxx).

    dcvSlicerHarness.py MODULE REPORT [NAME=VALUE ...]

Reads the module's description from `MODULE --xml` (xml.etree, independently of the module's own parser),
takes each parameter's value from NAME=VALUE or else its <default>, and builds the command line as Slicer
does: the parameters with a flag as `--longflag VALUE` (or `-flag VALUE`), booleans as the bare flag when
true, `--returnparameterfile FILE` when the module returns values (outputs with neither flag nor index),
then the positional parameters ordered by <index>. Runs it and writes REPORT as `key = value` lines:
command, status, progress (the <filter-progress> values in order), filter-start and filter-end (how many
blocks), return.NAME for each value read back from the return parameter file (return-unknown for names the
description does not declare as returned), and stderr (lines joined by ' | ').
A NAME that is not a parameter of the description is an error (exit status 2), as is a missing index.
"""
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET


def main(argv):
    if len(argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    module, report = argv[1], argv[2]
    values = {}
    for item in argv[3:]:
        name, sep, value = item.partition("=")
        if not sep:
            print(f"harness: '{item}' is not NAME=VALUE", file=sys.stderr)
            return 2
        values[name] = value

    description = subprocess.run([module, "--xml"], capture_output=True, check=True).stdout
    root = ET.fromstring(description)
    parameters = [p for group in root.findall("parameters") for p in group if p.tag not in ("label", "description")]
    known = {p.findtext("name") for p in parameters}
    unknown = sorted(set(values) - known)
    if unknown:
        print(f"harness: {', '.join(unknown)}: not parameters of {os.path.basename(module)}", file=sys.stderr)
        return 2

    command = [module]
    positional = []
    returned = []
    for p in parameters:
        name = p.findtext("name")
        value = values.get(name, p.findtext("default"))
        index = p.findtext("index")
        flag = p.findtext("flag")
        longflag = p.findtext("longflag")
        if index is not None:
            if value is None:
                print(f"harness: parameter {name} (index {index}) needs a value", file=sys.stderr)
                return 2
            positional.append((int(index), value))
            continue
        if flag is None and longflag is None:
            if p.findtext("channel") == "output":
                returned.append(name)
            continue
        option = "--" + longflag.lstrip("-") if longflag else "-" + flag.lstrip("-")
        if p.tag == "boolean":
            if (value or "").strip().lower() == "true":
                command.append(option)
            continue
        if value is None or value == "":
            continue
        command += [option, value]
    parameter_file = report + ".params"
    if os.path.exists(parameter_file):
        os.remove(parameter_file)
    if returned:
        command += ["--returnparameterfile", parameter_file]
    command += [value for _, value in sorted(positional)]

    run = subprocess.run(command, capture_output=True, text=True)
    lines = [
        "command = " + " ".join(command),
        f"status = {run.returncode}",
        "progress = " + " ".join(re.findall(r"<filter-progress>([^<]*)</filter-progress>", run.stdout)),
        f"filter-start = {run.stdout.count('<filter-start>')}",
        f"filter-end = {run.stdout.count('<filter-end>')}",
    ]
    if os.path.exists(parameter_file):
        with open(parameter_file) as f:
            for line in f:
                name, sep, value = line.partition("=")
                if not sep:
                    continue
                name = name.strip()
                key = "return." + name if name in returned else "return-unknown"
                lines.append(f"{key} = {value.strip() if key != 'return-unknown' else name}")
    lines.append("stderr = " + " | ".join(run.stderr.strip().splitlines()))
    with open(report, "w") as out:
        out.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
