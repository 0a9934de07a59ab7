"""Inside Blender: prints ``MIMETIC_JSON {"blender": VERSION}``, proving that bpy runs."""

import json

import bpy

print("MIMETIC_JSON " + json.dumps({"blender": bpy.app.version_string}))
