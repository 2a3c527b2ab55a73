-- How each verdict's suspect was brought into the control polyhedron's vertex order and frame
-- (registration/resynchronize.h): 'polyhedron', 'subdivided' or 'surface-fit' for the best
-- candidate, '' when no candidate was resynchronised (and for rows older than this migration
-- that did not record it). resync_residual: RMS of what the alignment could not explain,
-- relative to the control polyhedron's bounding-box diagonal.
ALTER TABLE detections ADD COLUMN resync_method TEXT NOT NULL DEFAULT '';
ALTER TABLE detections ADD COLUMN resync_residual REAL;
-- Builds of 2026-12-01 before this migration kept both in details_json.
UPDATE detections
   SET resync_method = COALESCE(json_extract(details_json, '$.resync_method'), ''),
       resync_residual = json_extract(details_json, '$.resync_residual')
 WHERE json_valid(details_json) AND json_type(details_json, '$.resync_method') = 'text';
