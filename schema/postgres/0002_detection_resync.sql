-- schema/0002_detection_resync.sql: how each verdict's suspect was resynchronised (registration/
-- resynchronize.h): 'polyhedron', 'subdivided' or 'surface-fit', '' when none was; the residual
-- relative to the control polyhedron's bounding-box diagonal.
ALTER TABLE detections ADD COLUMN resync_method text NOT NULL DEFAULT '';
ALTER TABLE detections ADD COLUMN resync_residual double precision;
UPDATE detections
   SET resync_method = COALESCE(details_json::jsonb ->> 'resync_method', ''),
       resync_residual = (details_json::jsonb ->> 'resync_residual')::double precision
 WHERE jsonb_typeof(details_json::jsonb -> 'resync_method') = 'string';
