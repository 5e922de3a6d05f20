"""The marker panel's files and models: panel_files (PANEL.yaml, CAMERA.yaml and hand-eye
files, resolved and loaded), panel_assets (the panel's model generated from its file; its
own main() writes models/panel/) and panel_camera_rig (a free camera in front of the
panel, the reference rig of the marker studies)."""
