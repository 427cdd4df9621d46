#!/usr/bin/env node
// Validate glTF 2.0 files (.gltf with external resources, or .glb) with the
// Khronos glTF-Validator (npm package `gltf-validator`, pinned in
// scripts/package-lock.json).
//
// Usage:
//   npm ci --prefix scripts
//   node scripts/validate_gltf.mjs [--verbose] FILE...
//
// Prints one summary line per file with its error/warning/info/hint counts,
// followed by every error and warning (severity, code, JSON pointer, message).
// With --verbose, infos and hints are listed as well.
//
// Exit status: 0 when every file has neither errors nor warnings, 1 when any
// file has at least one error or warning (or could not be read at all),
// 2 on a usage error.

import { readFile } from 'node:fs/promises';
import path from 'node:path';
import * as validator from 'gltf-validator';

const SEVERITY = ['error', 'warning', 'info', 'hint'];

function usage(stream) {
  stream.write('usage: node scripts/validate_gltf.mjs [--verbose] FILE...\n');
}

function parseArgs(argv) {
  const files = [];
  let verbose = false;
  let endOfOptions = false;
  for (const arg of argv) {
    if (!endOfOptions && arg === '--') {
      endOfOptions = true;
    } else if (!endOfOptions && (arg === '-v' || arg === '--verbose')) {
      verbose = true;
    } else if (!endOfOptions && (arg === '-h' || arg === '--help')) {
      usage(process.stdout);
      process.exit(0);
    } else if (!endOfOptions && arg.startsWith('-')) {
      process.stderr.write(`validate_gltf: unknown option ${arg}\n`);
      usage(process.stderr);
      process.exit(2);
    } else {
      files.push(arg);
    }
  }
  if (files.length === 0) {
    usage(process.stderr);
    process.exit(2);
  }
  return { files, verbose };
}

// Load a resource referenced by `uri` relative to the asset at `assetPath`.
// data: URIs never reach this function; the validator decodes them itself.
function externalResourceLoader(assetPath) {
  const baseDir = path.dirname(path.resolve(assetPath));
  return async (uri) => {
    const resolved = path.resolve(baseDir, decodeURIComponent(uri));
    try {
      return new Uint8Array(await readFile(resolved));
    } catch (err) {
      // A rejection makes the validator report IO_ERROR (an error) for this
      // resource, which is what we want: a missing .bin must fail the check.
      throw `${uri}: ${err.message}`;
    }
  };
}

async function validateFile(file) {
  let bytes;
  try {
    bytes = new Uint8Array(await readFile(file));
  } catch (err) {
    return { fatal: `cannot read file: ${err.message}` };
  }
  const ext = path.extname(file).toLowerCase();
  const options = {
    uri: path.basename(file),
    maxIssues: 0, // unlimited
    writeTimestamp: false,
    externalResourceFunction: externalResourceLoader(file),
  };
  if (ext === '.glb') options.format = 'glb';
  else if (ext === '.gltf') options.format = 'gltf';
  try {
    return { report: await validator.validateBytes(bytes, options) };
  } catch (err) {
    // Rejection: invalid arguments or the format could not be detected.
    return { fatal: `validator rejected the file: ${err}` };
  }
}

function formatIssue(msg) {
  const sev = SEVERITY[msg.severity] ?? `severity ${msg.severity}`;
  const where = msg.pointer ?? (msg.offset !== undefined ? `@byte ${msg.offset}` : '-');
  return `    ${sev.padEnd(7)} ${msg.code} ${where}: ${msg.message}`;
}

async function main() {
  const { files, verbose } = parseArgs(process.argv.slice(2));
  console.log(`glTF-Validator ${validator.version()}`);
  let failed = 0;
  for (const file of files) {
    const { report, fatal } = await validateFile(file);
    if (fatal) {
      failed += 1;
      console.log(`FAIL ${file}: ${fatal}`);
      continue;
    }
    const issues = report.issues;
    const bad = issues.numErrors > 0 || issues.numWarnings > 0;
    if (bad) failed += 1;
    const info = report.info ?? {};
    const extra = [];
    if (info.generator) extra.push(`generator "${info.generator}"`);
    if (info.animationCount !== undefined) extra.push(`${info.animationCount} animations`);
    if (info.totalVertexCount !== undefined) extra.push(`${info.totalVertexCount} vertices`);
    console.log(
      `${bad ? 'FAIL' : 'ok  '} ${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
        `${issues.numInfos} infos, ${issues.numHints} hints` +
        (extra.length ? ` (${extra.join(', ')})` : ''),
    );
    for (const msg of issues.messages) {
      if (verbose || msg.severity <= 1) console.log(formatIssue(msg));
    }
  }
  // Deliberately not phrased as "N passed, N failed": CI tooling reads that
  // wording as a test runner's closing line.
  console.log(`validate_gltf: ${files.length - failed} of ${files.length} files clean`);
  process.exitCode = failed > 0 ? 1 : 0;
}

main().catch((err) => {
  console.error(`validate_gltf: internal error: ${err?.stack ?? err}`);
  process.exit(1);
});
